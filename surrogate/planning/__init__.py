"""Which runs to make next: CFD runs that would settle the maps, bench runs that would tell
look-alike explanations apart."""
