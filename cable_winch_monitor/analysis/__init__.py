"""The model-versus-measurement loop: compare, diagnose, fit, report."""
