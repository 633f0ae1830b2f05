"""Publish/subscribe transports: the in-process mock broker, paho on a real broker, Mosquitto's configuration."""
