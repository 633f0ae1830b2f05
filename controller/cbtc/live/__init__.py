"""The zone and its fleet on a real broker: keys, credentials, the live loop."""
