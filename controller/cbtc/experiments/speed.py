"""How fast the testbed runs, each figure beside its reference measured in the same run.

- **sim**: simulated seconds per wall second for a fleet, and the same world with a controller that does nothing
  (its reports unanswered, no cycle: the trains stand) as the reference for the simulation's own overhead; the
  controller's share is the time the zone's report handling and cycles take inside the full run (each call clocked:
  the trains it moves cost the world and the boards more than standing ones, so the full run less the reference
  overstates it); beside it the traffic the speed follows: reports a train-second, commands a report, and the full
  run's wall time per report. Each is run `--runs` times (3) in turn and the fastest run counts, as timeit counts
  it: every run does the same work, and a first run also pays for first uses (imports inside functions, caches).
- **fusion**: wall time of one train-update (predict 50 ms, odometer, IPS fix) of our filter and of filterpy's
  UnscentedKalmanFilter on the same inputs, over a fleet, with the largest difference between the two.
- **controller**: wall time a zone takes per report (its cycles included), replaying a simulated run's reports, beside
  the same reports only decoded and authenticated.
- **memory**: how a simulation's resident memory grows per simulated hour (6 trains), beside the same run keeping
  every sample, each in a fresh process.
- **build**: the compiled build (setup.py) beside its own Python source (CBTC_PURE=1), each in a fresh process in
  turn: a simulation's real-time factor (11 trains on lego_oval) and a zone's time per report (50 trains), and whether
  the two ran the same simulation.
- **startup**: wall time and peak resident memory of commands that do little (`cbtc --help`, a command's `--help`)
  beside `python -c pass`.
"""

import json
import os
import subprocess
import sys
import time
from dataclasses import replace

SIM_CASES = (("itb_square", 2), ("lego_oval", 11), ("lego_long_oval", 50))


def sim_speed(layout_name: str, n_trains: int, duration_s: float, seed: int = 0, runs: int = 3) -> dict:
    """Real-time factor of `n_trains` on `layout_name` for `duration_s` simulated seconds (the paper's scenario for
    two trains on a layout with its stations), and of the same world under a do-nothing controller: `runs` fresh
    simulations of each, in turn. Every run does the same work (the same seed), so the fastest of each is the figure
    (timeit's rule: a slower run was slowed by what else the machine ran); every run's factor is listed beside it."""
    from cbtc.layout_files import load_layout
    from cbtc.zone.config import paper_scenario, queue_scenario

    layout = load_layout(layout_name)
    names = {st.name for st in layout.stations}
    if n_trains == 2 and {"main", "A", "B"} <= names:
        config = paper_scenario(layout, seed=seed, laps=None, duration_s=duration_s)
    else:
        config = queue_scenario(layout, n_trains, seed=seed, duration_s=duration_s)
    config = replace(config, laps=None)
    fulls, idles = [], []
    for _ in range(runs):
        fulls.append(_timed_run(config, full=True))
        idles.append(_timed_run(config, full=False))
    best = min(fulls, key=lambda run: run["wall_s"])
    idle_s = min(run["wall_s"] for run in idles)
    summary, reports, commands = best["summary"], best["reports"], best["commands"]
    simulated_s = summary["simulated_s"]
    full_s = best["wall_s"]
    return {"layout": layout.name, "trains": n_trains, "simulated_s": simulated_s, "wall_s": round(full_s, 3),
            "real_time_factor": round(simulated_s / full_s, 2), "runs": runs,
            "real_time_factors": [round(simulated_s / run["wall_s"], 2) for run in fulls],
            "reports_per_train_s": round(reports / n_trains / simulated_s, 1) if simulated_s else None,
            "commands_per_report": round(commands / reports, 2) if reports else None,
            "us_per_report": round(1e6 * full_s / reports, 1) if reports else None,
            "reference_wall_s": round(idle_s, 3), "reference_real_time_factor": round(simulated_s / idle_s, 2),
            "reference_real_time_factors": [round(simulated_s / run["wall_s"], 2) for run in idles],
            "controller_share": round(best["zone_s"] / full_s, 3),
            "collisions": summary["collisions"], "authority_overruns": summary["authority_overruns"],
            "emergency_trips": summary["emergency_trips"]}


def _timed_run(config, full: bool) -> dict:
    """One fresh simulation of `config`, clocked: the full one with the zone's own time inside it (its report handling
    and its cycles, each call clocked), or the world alone under a silent zone."""
    from cbtc.sim.simulation import Simulation

    sim = Simulation(config)   # built outside the timing: its first build imports the filter's modules
    zone_s = [0.0]
    if full:
        def timed(fn):
            def call(*args):
                begun = time.perf_counter()
                try:
                    return fn(*args)
                finally:
                    zone_s[0] += time.perf_counter() - begun
            return call

        sim.wrap_zone(timed)
    else:
        sim.silence_zone()
    started = time.perf_counter()
    recorder = sim.run()
    wall_s = time.perf_counter() - started
    if not full:
        return {"wall_s": wall_s}
    # the traffic the speed follows: reports the zone took and commands it sent (counted here, so that no run's
    # objects stay alive into the next)
    states = sim.zc.trains.values()
    return {"wall_s": wall_s, "zone_s": zone_s[0], "summary": recorder.summary(),
            "reports": sum(st.reports_taken for st in states), "commands": sum(st.cmd_seq for st in states)}


def fusion_speed(n_trains: int = 50, steps: int = 40, seed: int = 0) -> dict:
    """Wall time (us) of a train-update, ours and filterpy's (ReferenceUkf: the same steps done by filterpy), over
    `n_trains` filters for `steps` steps each, and the largest difference between the two."""
    import numpy as np

    from cbtc.estimation.reference_ukf import ReferenceUkf
    from cbtc.estimation.track_ukf import TrackUkf
    from cbtc.estimation.ukf_model import NoiseModel
    from cbtc.layout_files import load_layout

    layout = load_layout("lego_long_oval")
    rng = np.random.default_rng(seed)
    noise = NoiseModel(0.01, 1e-4, 1e-6, 1e-6, 4e-4, 1e-4, 0.02, 0.999)
    dt_s = 0.05
    starts = [(np.array([rng.uniform(0.5, layout.length_m - 0.5), 0.4, 0.0, 0.01]),
               np.diag([1e-4, 1e-3, 1e-6, 1e-4])) for _ in range(n_trains)]
    inputs = [[(0.4 * dt_s * (k + 1) * 1.01 + rng.normal(0, 0.001),
                layout.xy_m(x0[0] + 0.4 * dt_s * (k + 1)) + rng.normal(0, 0.02, 2)) for k in range(steps)]
              for x0, _P0 in starts]

    def run(kind):
        filters = [kind(layout, noise, x0, P0, 0.0) for x0, P0 in starts]
        taken = 0
        started = time.perf_counter()
        for f, seq in zip(filters, inputs):
            for k, (odo_m, (px, py)) in enumerate(seq):
                f.predict_to(dt_s * (k + 1))
                f.update_odometer(odo_m)
                taken += f.update_ips(px, py)
        return filters, taken, time.perf_counter() - started

    ours, ours_taken, ours_s = run(TrackUkf)
    refs, ref_taken, ref_s = run(ReferenceUkf)
    updates = n_trains * steps
    diff_x = max(float(np.max(np.abs(f.x - r.x))) for f, r in zip(ours, refs))
    diff_p = max(float(np.max(np.abs(f.P - r.P))) for f, r in zip(ours, refs))
    return {"trains": n_trains, "steps": steps, "ours_us": round(1e6 * ours_s / updates, 1),
            "filterpy_us": round(1e6 * ref_s / updates, 1), "speedup": round(ref_s / ours_s, 2),
            "fixes_used": ours_taken, "filterpy_fixes_used": ref_taken,
            "max_state_difference": diff_x, "max_covariance_difference": diff_p}


class _NullClient:
    """A bus client that takes every command and delivers nothing: the controller's own work, measured alone."""

    def __init__(self):
        self.published = 0

    def subscribe(self, topic_filter, callback):
        pass

    def unsubscribe(self, topic_filter):
        pass

    def publish(self, topic, payload, retain=False):
        self.published += 1


def controller_speed(n_trains: int = 50, duration_s: float = 10.0, seed: int = 0) -> dict:
    """Wall time (us) a zone controller takes per report, its cycles included, replaying the reports of a simulated
    run of `n_trains` on lego_long_oval (or lego_oval up to 11) into a zone of the same session; beside it, the
    same reports only decoded and authenticated (the wire's share)."""
    import logging

    from cbtc.layout_files import load_layout
    from cbtc.protocol import fast_wire, wire
    from cbtc.sim.simulation import FIRST_CYCLE_S, Simulation
    from cbtc.zone.config import queue_scenario, train_key
    from cbtc.zone.factory import build_zone

    layout = load_layout("lego_oval" if n_trains <= 11 else "lego_long_oval")
    config = queue_scenario(layout, n_trains, seed=seed, duration_s=duration_s)
    sim = Simulation(config, keep_reports=True)
    sim.run()
    heard = sim.recorder.heard()
    keys = {spec.train_id: train_key(seed, spec.train_id) for spec in config.trains}
    now = [0.0]
    client = _NullClient()
    zc = build_zone(config, keys, client, lambda: now[0], seed=config.seed)   # the run's session: reports answer it
    zc.clear_track(None, by="the replayed run, from its truth,")   # its trains alone stand on the track
    zc.start()
    logger = logging.getLogger("cbtc")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        next_cycle_s = FIRST_CYCLE_S
        started = time.perf_counter()
        for recv_s, topic, payload in heard:
            while next_cycle_s <= recv_s:
                now[0] = next_cycle_s
                zc.cycle(next_cycle_s)
                next_cycle_s += config.cycle_s
            now[0] = recv_s
            zc.on_report(topic, payload)
        zone_s = time.perf_counter() - started
    finally:
        logger.setLevel(level)
    started = time.perf_counter()
    for _recv_s, topic, payload in heard:
        fast_wire.decode_report(keys[wire.train_id_of(topic)], topic, payload)
    wire_s = time.perf_counter() - started
    n = max(1, len(heard))
    return {"trains": n_trains, "layout": layout.name, "reports": len(heard), "commands": client.published,
            "zone_us_per_report": round(1e6 * zone_s / n, 1), "decode_us_per_report": round(1e6 * wire_s / n, 1),
            "zone_over_decode": round(zone_s / wire_s, 2) if wire_s else None}


def _in_build(pure: bool, argv) -> dict:
    """The JSON a `cbtc bench` run prints, run in a fresh process of the compiled build or of its source."""
    env = dict(os.environ, CBTC_PURE="1" if pure else "0")
    out = subprocess.run([sys.executable, "-m", "cbtc.cli", "bench", *argv, "--json"], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout)


def build_speed(duration_s: float = 10.0, seed: int = 0) -> dict:
    """The compiled build beside its source: a simulation's real-time factor (11 trains on lego_oval) and a zone's time
    per report (50 trains), each build in a fresh process in turn; {"compiled_modules": 0} alone for a plain install."""
    sim_argv = ["sim", "--layout", "lego_oval", "--trains", "11", "--duration", str(duration_s), "--seed", str(seed)]
    zone_argv = ["controller", "--trains", "50", "--duration", str(duration_s), "--seed", str(seed)]
    compiled_sim = _in_build(False, sim_argv)
    modules = compiled_sim["machine"]["compiled_modules"]
    if not modules:
        return {"compiled_modules": 0}
    pure_sim = _in_build(True, sim_argv)
    compiled_zone, pure_zone = _in_build(False, zone_argv), _in_build(True, zone_argv)
    fast, slow = compiled_sim["sim"][0], pure_sim["sim"][0]
    same = ("collisions", "authority_overruns", "emergency_trips", "reports_per_train_s", "commands_per_report")
    zone_fast, zone_slow = compiled_zone["controller"][0], pure_zone["controller"][0]
    return {"compiled_modules": modules,
            "sim_layout": fast["layout"], "sim_trains": fast["trains"],
            "sim_real_time_factor": fast["real_time_factor"], "pure_sim_real_time_factor": slow["real_time_factor"],
            "sim_speedup": round(fast["real_time_factor"] / slow["real_time_factor"], 2),
            "same_simulation": all(fast[k] == slow[k] for k in same),
            "zone_trains": zone_fast["trains"], "zone_us_per_report": zone_fast["zone_us_per_report"],
            "pure_zone_us_per_report": zone_slow["zone_us_per_report"],
            "zone_speedup": round(zone_slow["zone_us_per_report"] / zone_fast["zone_us_per_report"], 2),
            "same_commands": zone_fast["commands"] == zone_slow["commands"]}


def _resident_mib() -> float:
    """This process's resident memory now (MiB), from /proc (Linux); its peak where /proc is missing."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def memory_run(n_trains: int, duration_s: float, seed: int, keep_samples: bool) -> dict:
    """Resident memory (MiB) of `n_trains` on lego_oval after a tenth of `duration_s` simulated seconds (imports,
    filters, the broker's queues all built) and at the end, in this process."""
    import gc

    from cbtc.layout_files import load_layout
    from cbtc.sim.simulation import Simulation
    from cbtc.zone.config import queue_scenario

    config = queue_scenario(load_layout("lego_oval"), n_trains, seed=seed, duration_s=duration_s)
    sim = Simulation(config, keep_samples=keep_samples)
    warm_s = duration_s / 10.0
    sim.scheduler.run_until(warm_s)
    gc.collect()
    warm_mib = _resident_mib()
    summary = sim.run().summary()
    gc.collect()
    end_mib = _resident_mib()
    return {"warm_mib": round(warm_mib, 1), "end_mib": round(end_mib, 1),
            "growth_mib_per_hour": round((end_mib - warm_mib) / (summary["simulated_s"] - warm_s) * 3600.0, 1),
            "collisions": summary["collisions"], "authority_overruns": summary["authority_overruns"]}


def memory_growth(n_trains: int = 6, duration_s: float = 600.0, seed: int = 0) -> dict:
    """How the resident memory of a simulation grows per simulated hour: the run as `cbtc sim` makes it (running
    statistics) beside the same run keeping every sample (what a plot asks for), each in a fresh process."""
    rows = {}
    for name, keep in (("statistics", False), ("every_sample", True)):
        code = ("import json, sys\nfrom cbtc.experiments.speed import memory_run\n"
                f"print(json.dumps(memory_run({n_trains}, {duration_s!r}, {seed}, {keep})))")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
        rows[name] = json.loads(out.stdout)
    return {"trains": n_trains, "layout": "lego_oval", "simulated_s": duration_s, **rows["statistics"],
            "reference_growth_mib_per_hour": rows["every_sample"]["growth_mib_per_hour"]}


STARTUP_COMMANDS = (("python -c pass", [sys.executable, "-c", "pass"]),
                    ("cbtc --help", [sys.executable, "-m", "cbtc.cli", "--help"]),
                    ("cbtc sim --help", [sys.executable, "-m", "cbtc.cli", "sim", "--help"]),
                    ("cbtc zone --help", [sys.executable, "-m", "cbtc.cli", "zone", "--help"]))


# a small launcher starts each command, so that the child's peak resident memory is its own and not this process's
# (a forked child counts its parent's pages until it runs the command)
_LAUNCHER = ("import resource, subprocess, sys, time\n"
             "t = time.perf_counter()\n"
             "subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)\n"
             "print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def _one_run(argv):
    """(wall s, peak resident MiB) of one process."""
    out = subprocess.run([sys.executable, "-c", _LAUNCHER, *argv], capture_output=True, text=True, check=True)
    wall_s, rss_kib = out.stdout.split()
    return float(wall_s), int(rss_kib) / 1024.0


def startup(runs: int = 5) -> list:
    """Median wall time and peak resident memory of each of STARTUP_COMMANDS over `runs` runs, taken in turn, and
    the ratio of each to `python -c pass`."""
    import statistics
    samples = {name: [] for name, _argv in STARTUP_COMMANDS}
    for _ in range(runs):
        for name, argv in STARTUP_COMMANDS:
            samples[name].append(_one_run(argv))
    base_s = statistics.median(w for w, _m in samples["python -c pass"])
    rows = []
    for name, _argv in STARTUP_COMMANDS:
        wall_s = statistics.median(w for w, _m in samples[name])
        rows.append({"command": name, "wall_s": round(wall_s, 3), "resident_mib": round(max(m for _w, m in
                                                                                           samples[name]), 1),
                     "vs_python": round(wall_s / base_s, 2)})
    return rows
