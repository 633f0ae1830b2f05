"""The project's exceptions: each subclasses a builtin and carries a message that names the input and the fix."""


class CbtcError(Exception):
    """Base class of every error this package raises on purpose."""


class LayoutError(CbtcError, ValueError):
    """A track layout file is invalid; the message names the file, the key and what to fix."""


class ConfigError(CbtcError, ValueError):
    """A train profile, scenario or command-line setting is invalid."""


class BusError(CbtcError, ConnectionError):
    """The message bus (mock broker or a real MQTT broker) failed or refused us."""


class BoardError(CbtcError, OSError):
    """A train board could not be reached, written or verified; the message names the port and what to do."""
