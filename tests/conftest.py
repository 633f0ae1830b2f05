"""Shared pytest fixtures."""

import pytest


@pytest.fixture(scope="session")
def mpy_tree(tmp_path_factory):
    """The firmware, host shims, fakes and umqtt compiled to .mpy in one folder, for the MicroPython unix port."""
    from mpy_harness import build_tree

    return build_tree(str(tmp_path_factory.mktemp("mpy_tree")))


from mosquitto_fixture import mosquitto, secured_mosquitto  # noqa: E402,F401  (real-broker fixtures)
