"""Messages as records whose fields are named by the message table (messages.py): what the zone builds a command as
and keeps of the newest one it sent."""

from collections import namedtuple

from cbtc.firmware import messages

# a command's fields after the header, in the table's order: `fast_wire.encode_command(key, id, *command)` seals it
Command = namedtuple("Command", messages.names(messages.COMMAND))
