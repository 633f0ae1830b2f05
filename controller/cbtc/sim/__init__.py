"""The simulated world: virtual trains, simulated drivers, scenarios and their recorder (the only place truth is
read)."""
