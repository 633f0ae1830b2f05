"""CPython has no time.ticks_us: MicroPython's, for the firmware's drivers when the host checks run them under
CPython (a microsecond counter wrapping at 2^30, as on the ESP8266). Never loaded under MicroPython."""

from time import perf_counter_ns


def ticks_us():
    return (perf_counter_ns() // 1000) & 0x3FFFFFFF


def ticks_diff(a, b):
    return ((a - b + 0x20000000) & 0x3FFFFFFF) - 0x20000000
