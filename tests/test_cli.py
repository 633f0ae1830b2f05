"""The command line as a whole: its version, and a reader that leaves early."""

import os
import subprocess
import sys

import pytest

from cbtc.cli import main


def test_version_names_the_installed_package(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("cbtc ")


def test_a_reader_that_closed_its_end_of_the_pipe_ends_the_command_quietly():
    """`cbtc layout show lego_oval | head -c 1`, made certain: the pipe's read end is closed before the command starts,
    so its first write meets a closed pipe. It exits 0 with nothing on stderr (no BrokenPipeError traceback)."""
    read_fd, write_fd = os.pipe()
    os.close(read_fd)
    try:
        done = subprocess.run([sys.executable, "-m", "cbtc.cli", "layout", "show", "lego_oval"], stdout=write_fd,
                              stderr=subprocess.PIPE, timeout=120)
    finally:
        os.close(write_fd)
    assert done.returncode == 0 and done.stderr == b"", done.stderr.decode()
