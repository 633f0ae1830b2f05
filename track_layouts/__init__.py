"""Track layouts shipped with the package (YAML)."""
