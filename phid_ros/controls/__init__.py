"""Excitation systems and turbine-governors: models declared once, identified from recordings."""
