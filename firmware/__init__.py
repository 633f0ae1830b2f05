"""Firmware files shipped inside the controller package so `cbtc flash` and the virtual trains find them."""
