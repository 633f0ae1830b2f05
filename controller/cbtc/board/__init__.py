"""Real boards: precompiling and flashing the firmware, calibrating a board's sensors."""
