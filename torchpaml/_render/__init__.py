"""Presentation: result objects to figures, tables, JSON and the HTML report. The numerics never import it."""
