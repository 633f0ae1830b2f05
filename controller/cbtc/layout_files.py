"""Layout files: the YAML files of a user or the layouts shipped with the package, read and checked.

`load_layout(path_or_name)` raises LayoutError naming the file, the key path and the fix.
"""

import os
from importlib import resources

import yaml

from cbtc.errors import LayoutError
from cbtc.railway.layout import Layout
from cbtc.railway.layout_dict import layout_from_dict


def layout_names():
    """Names of the layouts shipped with the package (without `.yaml`)."""
    folder = resources.files("cbtc.track_layouts")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def resolve_layout(path_or_name):
    """A readable file path for a file path or a packaged layout name."""
    text = str(path_or_name)
    if os.path.isfile(text):
        return text
    bare = text[:-5] if text.endswith(".yaml") else text
    if "/" not in bare and os.sep not in bare:
        packaged = resources.files("cbtc.track_layouts") / f"{bare}.yaml"
        if packaged.is_file():
            return str(packaged)
    raise LayoutError(f"layout {text!r} not found: give a YAML file path or one of the packaged layouts "
                      f"{layout_names()}")


def load_layout(path_or_name) -> Layout:
    """Load and validate a layout from a YAML file path or a packaged name such as "itb_square"."""
    source = resolve_layout(path_or_name)
    try:
        with open(source, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as exc:
        raise LayoutError(f"{source}: not valid YAML: {' '.join(str(exc).split())}; fix the syntax there") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LayoutError(f"{source}: cannot read it as a UTF-8 text file: {exc}") from None
    return layout_from_dict(data, source)
