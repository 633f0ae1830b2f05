"""The IPS coordinate frame: Marvelmind beacons report in their own frame; the track is drawn in the layout frame.

track = origin + R(rotation) * ips. Pure functions on floats or numpy arrays.
"""

from math import cos, radians, sin


def ips_to_track(x_m, y_m, frame):
    """Layout-frame (x, y) in metres of an IPS-frame position."""
    c, s = cos(radians(frame.rotation_deg)), sin(radians(frame.rotation_deg))
    return frame.origin_x_m + c * x_m - s * y_m, frame.origin_y_m + s * x_m + c * y_m


def track_to_ips(x_m, y_m, frame):
    """IPS-frame (x, y) in metres of a layout-frame position."""
    c, s = cos(radians(frame.rotation_deg)), sin(radians(frame.rotation_deg))
    dx, dy = x_m - frame.origin_x_m, y_m - frame.origin_y_m
    return c * dx + s * dy, -s * dx + c * dy
