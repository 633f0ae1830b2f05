"""Sub-commands of the `cbtc` command line, one module each (see cbtc.cli)."""
