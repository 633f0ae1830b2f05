"""The railway as values: track geometry, layouts, trains and their physics, balise telegrams (pure)."""
