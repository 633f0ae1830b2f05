"""Scenario files shipped with the package (YAML): `cbtc sim --scenario NAME`."""
