"""Figures (matplotlib), the browser viewer and reports."""
