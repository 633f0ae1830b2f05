"""Where a campaign's runs are made and kept: worker processes on this machine or a Dask distributed cluster, and a
results file of one JSON line per finished run, so that a stopped campaign, run again, makes only the missing runs."""

import json
import os
from concurrent.futures import ProcessPoolExecutor, as_completed

from cbtc.errors import ConfigError
from cbtc.experiments.campaign import code_fingerprint, run_one


class ResultsFile:
    """The finished runs of a campaign, one JSON line each, keyed by their `cbtc sim` command. Only runs made by this
    code (campaign.code_fingerprint) are reused; `other_code` counts the others, which are made again."""

    def __init__(self, path: str):
        self.path = path
        self.records = {}
        self.unreadable = 0   # lines that are no record (a line cut short when a campaign was killed): run again
        self.other_code = 0
        directory = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(directory):
            raise ConfigError(f"--results {path}: directory {directory} does not exist; create it or give another")
        if os.path.isdir(path):
            raise ConfigError(f"--results {path} is a directory; give a file name")
        self._cut_short = False   # the file ends inside a line: the next record starts on a line of its own
        code = code_fingerprint()
        if os.path.exists(path):
            with open(path) as fh:
                for line in fh:
                    self._cut_short = not line.endswith("\n")
                    try:
                        record = json.loads(line)
                        if record.get("code") != code:
                            self.other_code += 1
                            continue
                        self.records[record["command"]] = record
                    except (ValueError, KeyError, TypeError, AttributeError):
                        self.unreadable += bool(line.strip())

    def add(self, record: dict) -> None:
        """Keep a finished run: appended and flushed at once, so a kill loses at most the run being written."""
        self.records[record["command"]] = record
        with open(self.path, "a") as fh:
            fh.write(("\n" if self._cut_short else "") + json.dumps(record, sort_keys=True) + "\n")
        self._cut_short = False

    def clear(self) -> None:
        """Forget every run: the file starts empty."""
        self.records.clear()
        self._cut_short = False
        open(self.path, "w").close()


def run_local(specs, workers: int, on_done) -> None:
    """Make `specs` in `workers` processes; `on_done(record)` for each as it finishes (in the calling process)."""
    if workers == 1:
        for spec in specs:
            on_done(run_one(spec))
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(run_one, spec) for spec in specs]
        try:
            for future in as_completed(futures):
                on_done(future.result())
        except BaseException:
            for future in futures:
                future.cancel()
            raise


def run_dask(specs, address: str, on_done) -> None:
    """Make `specs` on the Dask distributed cluster whose scheduler is at `address` (its workers need cbtc
    installed); `on_done(record)` for each as it finishes."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ConfigError("--scheduler needs Dask distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, timeout="10s")
    except OSError as exc:
        raise ConfigError(f"--scheduler {address}: no Dask scheduler answers there ({exc}); start one with "
                          f"`dask scheduler` and workers with `dask worker {address}`") from None
    with client:
        futures = client.map(run_one, specs, pure=False)
        try:
            for future in dask_completed(futures):
                on_done(future.result())
        except BaseException:
            client.cancel(futures)
            raise
