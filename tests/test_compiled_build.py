"""The compiled build (setup.py) runs the same code as its Python source: the same seeded runs give the same truth,
estimates and commands to the last bit, and CBTC_PURE=1 loads the source instead. Without a compiled build (an
editable install) there is nothing to compare, and the comparison is skipped."""

import json
import os
import subprocess
import sys

import pytest

import cbtc

# a fault-free queue and runs of fault classes that take the estimator and the authority off the happy path
RUN = r"""
import hashlib, json, logging, sys
import cbtc
from cbtc.experiments import campaign
from cbtc.sim.simulation import Simulation
logging.getLogger("cbtc").setLevel(logging.CRITICAL)
specs = campaign.plan(8, [c for c in campaign.CLASSES if campaign.runs_on(c, "lego_oval")], ("lego_oval",), (3,), 30.0,
                      5)
specs += campaign.plan(2, ["none", "switch_stall"], ("lego_passing_loop",), (3,), 30.0, 5)
digest = hashlib.sha256()
for spec in specs:
    sim = Simulation(spec.config(), keep_samples=True)
    commands = []
    sim.zc.commands.subscribe(lambda sent: commands.append((sent.train_id, sent.command, sent.t_s)))
    rec = sim.run()
    for name in ("head_s_m", "v_mps", "est_s_m", "est_sigma_m") if hasattr(rec, "est_sigma_m") else ():
        for series in getattr(rec, name):   # a network's recorder keeps no samples: its summary and commands tell
            digest.update(series.tobytes())
    digest.update(repr(commands).encode())
    digest.update(json.dumps(rec.summary(), sort_keys=True).encode())
from cbtc.firmware.obu import OnboardUnit
from cbtc.zone.controller import ZoneController
slots = [cls.__name__ for cls, name in ((ZoneController, "layout"), (OnboardUnit, "train_id")) if name in vars(cls)]
print(json.dumps({"digest": digest.hexdigest(), "compiled": cbtc.compiled_modules(), "runs": len(specs),
                  "slots": slots}))
"""


def run(pure: bool) -> dict:
    env = dict(os.environ, CBTC_PURE="1" if pure else "0")
    out = subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_cbtc_pure_loads_every_module_from_its_source():
    code = ("import cbtc, cbtc.zone.controller, cbtc.sim.simulation, cbtc.firmware.obu; "
            "print(cbtc.compiled_modules(), cbtc.zone.controller.__file__, cbtc.firmware.obu.__file__)")
    out = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, CBTC_PURE="1"), capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split(" ")[0] == "[]" and out.stdout.strip().endswith(".py")


def test_the_compiled_build_gives_the_same_runs_as_its_source():
    compiled = run(pure=False)
    if not compiled["compiled"]:
        pytest.skip("this install is plain Python (editable, or built without a C compiler): nothing to compare")
    assert "cbtc.zone.controller" in compiled["compiled"] and "cbtc.firmware.obu" in compiled["compiled"]
    assert compiled["slots"] == ["ZoneController", "OnboardUnit"]   # their .pxd found: C types with slots
    pure = run(pure=True)
    assert pure["compiled"] == [] and pure["slots"] == []
    assert compiled["digest"] == pure["digest"]


def test_compiled_modules_names_only_compiled_ones():
    assert all(name.startswith("cbtc.") for name in cbtc.compiled_modules())
