"""Host stand-in for MicroPython's `network` module: one station interface that joins any network on the third
poll of isconnected() and reports a loopback address, so the firmware's sockets reach a broker on this host."""

STA_IF = 0


class WLAN:
    def __init__(self, *args):
        self.state = -1   # isconnected() polls since connect(); -1: never asked to connect

    def active(self, *args):
        return True

    def connect(self, *args):
        self.state = 0

    def isconnected(self):
        if self.state >= 0:
            self.state += 1
        return self.state > 2

    def ifconfig(self):
        return ("127.0.0.1", "255.0.0.0", "127.0.0.1", "127.0.0.1")
