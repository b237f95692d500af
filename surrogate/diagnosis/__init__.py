"""Which physical effect is a model missing? Candidates refitted, judged against the maps'
own error and on runs they were not fitted to, look-alikes grouped, sensors checked."""
