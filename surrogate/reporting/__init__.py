"""What users read and look at: HTML reports, figures and the diagnosis in words."""
