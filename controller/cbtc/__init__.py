"""lego-cbtc: Communication-Based Train Control at LEGO scale (zone controller, simulator, tools)."""

import os
import sys

__version__ = "0.1.0"


class _SourceFirst:
    """Under CBTC_PURE=1, every cbtc module loads from its .py source, never from a compiled form beside it (the
    compiled build's reference, and tracebacks with source lines)."""

    @staticmethod
    def find_spec(name, path, target=None):
        if path is None or not name.startswith("cbtc."):
            return None
        from importlib.util import spec_from_file_location
        leaf = name.rpartition(".")[2] + ".py"
        for folder in path:
            source = os.path.join(folder, leaf)
            if os.path.isfile(source):
                return spec_from_file_location(name, source)
        return None


if os.environ.get("CBTC_PURE", "") not in ("", "0"):
    sys.meta_path.insert(0, _SourceFirst)


def compiled_modules() -> list:
    """Names of the cbtc modules loaded so far from a compiled form (the compiled build; empty: plain Python)."""
    return sorted(name for name, module in list(sys.modules.items())
                  if name.startswith("cbtc.") and (getattr(module, "__file__", None) or "").endswith((".so", ".pyd")))
