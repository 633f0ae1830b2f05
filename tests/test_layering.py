"""The layering of pyproject.toml's import-linter contracts holds, and a broken contract is caught."""

import os
import shutil
import subprocess

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINT_IMPORTS = shutil.which("lint-imports")

pytestmark = pytest.mark.skipif(LINT_IMPORTS is None, reason="import-linter is not installed: pip install '.[test]'")


def _lint(config_path):
    return subprocess.run([LINT_IMPORTS, "--config", config_path, "--no-cache"], capture_output=True, text=True,
                          cwd=REPO, timeout=120)


def test_the_project_keeps_its_import_contracts():
    proc = _lint(os.path.join(REPO, "pyproject.toml"))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "0 broken" in proc.stdout


def test_a_contract_the_code_breaks_fails_the_check(tmp_path):
    # the simulator builds its zone controller, so forbidding that import must be reported as broken
    config = tmp_path / "contracts.toml"
    config.write_text('[tool.importlinter]\nroot_packages = ["cbtc"]\n\n'
                      '[[tool.importlinter.contracts]]\nname = "sim without zone"\ntype = "forbidden"\n'
                      'source_modules = ["cbtc.sim"]\nforbidden_modules = ["cbtc.zone"]\n')
    proc = _lint(str(config))
    assert proc.returncode != 0
    assert "BROKEN" in proc.stdout and "cbtc.sim" in proc.stdout
