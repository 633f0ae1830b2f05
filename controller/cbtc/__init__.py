"""lego-cbtc: Communication-Based Train Control at LEGO scale (zone controller, simulator, tools)."""

__version__ = "0.1.0"
