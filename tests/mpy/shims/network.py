"""Host stand-in for MicroPython's `network` module: one station interface, controllable from tests.

WLAN(STA_IF).connect(ssid, password) succeeds after CONNECT_POLLS calls of isconnected(), for any network while
NETWORKS is None, or when NETWORKS (ssid -> password) lists the ssid with that password; otherwise it never
connects. ifconfig() reports a loopback address so the firmware's sockets reach a broker on this host.
"""

STA_IF = 0
AP_IF = 1
NETWORKS = None
CONNECT_POLLS = 2
_IFACES = {}


class WLAN:
    def __new__(cls, interface=STA_IF):
        if interface not in _IFACES:
            iface = object.__new__(cls)
            iface.interface = interface
            iface._active = False
            iface._ssid = None
            iface._password = None
            iface._polls = 0
            iface.connects = 0
            _IFACES[interface] = iface
        return _IFACES[interface]

    def __init__(self, interface=STA_IF):
        pass

    def active(self, on=None):
        if on is None:
            return self._active
        self._active = bool(on)
        return None

    def connect(self, ssid=None, password=None):
        self._ssid = ssid
        self._password = password
        self._polls = 0
        self.connects += 1

    def disconnect(self):
        self._ssid = None

    def isconnected(self):
        if not self._active or self._ssid is None:
            return False
        if NETWORKS is not None and NETWORKS.get(self._ssid) != self._password:
            return False
        self._polls += 1
        return self._polls > CONNECT_POLLS

    def ifconfig(self):
        return ("127.0.0.1", "255.0.0.0", "127.0.0.1", "127.0.0.1")

    def config(self, *args, **kwargs):
        return None
