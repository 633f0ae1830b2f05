"""The train firmware (MicroPython), imported by the controller as this package: one OnboardUnit and one wire
protocol for boards and virtual trains. manifest.py lists what goes onto each board."""
