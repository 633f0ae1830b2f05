"""Device drivers for the train board; each takes ready bus and pin objects."""
