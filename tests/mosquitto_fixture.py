"""A private Mosquitto per test, on a free loopback port (imported by conftest.py).

`mosquitto`: an open broker (anonymous clients). `secured_mosquitto(train_ids)`: a broker with the configuration
`cbtc broker config` generates (passwords, per-train ACLs); returns (broker, {user: password}). Both can be killed
and started again on the same port. Tests that need them are marked `mosquitto` and skipped only when the binary is
absent.
"""

import json
import os

import pytest

from cbtc.bus.broker_config import (
    MosquittoProcess,
    free_port,
    mosquitto_exe,
    write_config,
)

requires_mosquitto = pytest.mark.skipif(not mosquitto_exe(), reason="mosquitto is not installed")


def _run_as():
    """Mosquitto started as root reads its files as user `mosquitto`; a test's private folder is root's alone."""
    return "root" if hasattr(os, "geteuid") and os.geteuid() == 0 else None


@pytest.fixture
def mosquitto(tmp_path):
    if not mosquitto_exe():
        pytest.skip("mosquitto is not installed")
    broker = MosquittoProcess.open_broker(str(tmp_path / "broker")).start()
    yield broker
    broker.kill()


@pytest.fixture
def secured_mosquitto(tmp_path):
    if not mosquitto_exe():
        pytest.skip("mosquitto is not installed")
    started = []

    def start(train_ids):
        port = free_port()
        paths = write_config(str(tmp_path / "secured"), train_ids, port=port, run_as=_run_as())
        broker = MosquittoProcess(paths["mosquitto.conf"], port).start()
        started.append(broker)
        with open(paths["credentials.json"]) as fh:
            return broker, json.load(fh)

    yield start
    for broker in started:
        broker.kill()
