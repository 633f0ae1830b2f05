"""The compiled build: the modules a report, a command and a simulated tick run through, on a simulated or a real
broker, compiled by Cython from their unchanged Python source (the same code; `cbtc bench build` measures it beside
the source). The .pxd files beside some of them make their
hottest classes C types that hold the attributes their methods set in slots, so that self.x is a field read rather
than a type and a dict lookup; any other attribute still goes to the instance __dict__. Some also type the arguments
of hot methods (a train's state, a report, the filter's states and events, the recorder's trains), so that their
fields are read the same way, and give the locals of the filter's predict and the speed envelope C double types: the
same operations in the same order.

Everything else is in pyproject.toml. The compiled build is asked for: `CBTC_COMPILE=1 pip install .` (minutes on a
small machine); a plain `pip install .` installs the package as plain Python in seconds, as does an editable install
(so that an edited .py is the code that runs) or a machine without a C compiler. At run time CBTC_PURE=1 loads the
.py source of every module instead of its compiled form (cbtc/__init__.py).
"""

import os
import shutil

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

COMPILED = (
    "cbtc/scheduler.py",
    "cbtc/estimation/track_ukf.py", "cbtc/estimation/ukf_model.py", "cbtc/estimation/ukf_estimator.py",
    "cbtc/estimation/ukf_history.py",
    "cbtc/estimation/ips_agreement.py", "cbtc/estimation/balise_reads.py", "cbtc/estimation/wheel_watch.py",
    "cbtc/estimation/speed_envelope.py",
    "cbtc/estimation/motor_gain.py", "cbtc/estimation/estimate.py", "cbtc/estimation/fix_consensus.py",
    "cbtc/zone/controller.py", "cbtc/zone/train_state.py", "cbtc/zone/plausibility.py", "cbtc/zone/boots.py",
    "cbtc/zone/refusals.py", "cbtc/zone/commanding.py", "cbtc/zone/estimators.py", "cbtc/zone/indexes.py",
    "cbtc/zone/stations.py", "cbtc/zone/fast_reports.py", "cbtc/zone/situations.py", "cbtc/zone/tails.py",
    "cbtc/authority/rules.py", "cbtc/authority/moving_block.py", "cbtc/authority/control_laws.py",
    "cbtc/authority/values.py",
    "cbtc/railway/geometry.py", "cbtc/railway/layout.py", "cbtc/railway/physics.py", "cbtc/railway/balise.py",
    "cbtc/railway/train_profile.py", "cbtc/railway/ips_frame.py",
    "cbtc/sim/simulation.py", "cbtc/sim/virtual_train.py", "cbtc/sim/drivers.py", "cbtc/sim/truth.py",
    "cbtc/sim/recorder.py", "cbtc/sim/tail_beacons.py", "cbtc/bus/mock_broker.py", "cbtc/protocol/fast_wire.py",
    "cbtc/bus/lean_bus.py", "cbtc/bus/net_loop.py", "cbtc/bus/mqtt_packets.py", "cbtc/bus/client.py",
    "cbtc/live/loop.py",
    "firmware/wire.py", "firmware/wire_zc.py", "firmware/obu.py", "firmware/telegram.py",
)

# Python's semantics kept exactly: annotations are not C types (an int passed as a float stays an int), so the
# compiled modules give the same results as their source (tests/test_compiled_build.py)
DIRECTIVES = {"language_level": 3, "binding": True, "annotation_typing": False}


def _extension(path):
    if path.startswith("firmware/"):
        name, source = "cbtc.firmware." + path[len("firmware/"):-3], path
    else:
        name, source = path[:-3].replace("/", "."), "controller/" + path
    return Extension(name, [source], optional=True)


def _firmware_pxds():
    """A directory where Cython finds firmware/*.pxd under the package the build gives them (cbtc.firmware): it
    looks a module's .pxd up by the module's full name."""
    root = os.path.join("build", "pxd")
    os.makedirs(os.path.join(root, "cbtc", "firmware"), exist_ok=True)
    for name in os.listdir("firmware"):
        if name.endswith(".pxd"):
            shutil.copyfile(os.path.join("firmware", name), os.path.join(root, "cbtc", "firmware", name))
    return root


class OptionalBuildExt(build_ext):
    """Compiles COMPILED with Cython when CBTC_COMPILE=1, or nothing at all (not asked, editable install, no
    Cython)."""

    def run(self):
        if getattr(self, "editable_mode", False) or self.inplace or os.environ.get("CBTC_COMPILE") != "1":
            self.extensions = []
            return
        try:
            from Cython.Build import cythonize
        except ImportError:
            self.warn("Cython is not installed: cbtc installs as plain Python")
            self.extensions = []
            return
        made = {ext.name: ext for ext in cythonize(self.extensions, build_dir="build/cython",
                                                   include_path=[_firmware_pxds()],
                                                   compiler_directives=DIRECTIVES, quiet=True)}
        for ext in self.extensions:   # setuptools' own Extension objects, their sources now the generated C
            ext.sources = made[ext.name].sources
        self.parallel = self.parallel or os.cpu_count() or 1
        super().run()

    def build_extensions(self):
        if self.compiler.compiler_type == "unix":
            # -O3 (Python's own level) without debug information: faster code for a longer build (cbtc bench build)
            for ext in self.extensions:
                ext.extra_compile_args = ["-O3", "-g0"]
        super().build_extensions()

    def get_outputs(self):
        return super().get_outputs() if self.extensions else []


setup(ext_modules=[_extension(path) for path in COMPILED], cmdclass={"build_ext": OptionalBuildExt})
