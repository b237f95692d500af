"""The measurement workbench: compare a model with bench data, diagnose, fit, and iterate."""
