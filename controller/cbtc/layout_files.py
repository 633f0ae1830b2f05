"""Layout files: the YAML files of a user or the layouts shipped with the package, read and checked.

`load_layout(path_or_name)` raises LayoutError naming the file, the key path and the fix.
"""

import os
from importlib import resources

import yaml

from cbtc.errors import LayoutError
from cbtc.railway.layout import Layout
from cbtc.railway.layout_dict import layout_from_dict
from cbtc.railway.network_layout import refuse_network
from cbtc.yaml_lines import YamlKeyError, load_with_lines


def packaged_names(package: str):
    """Names of the YAML files shipped in `package` (without `.yaml`)."""
    return sorted(p.name[:-5] for p in resources.files(package).iterdir() if p.name.endswith(".yaml"))


def resolve_packaged(path_or_name, package: str, what: str, error=LayoutError) -> str:
    """A readable file path for a file path or the name of a YAML file shipped in `package`; `error` naming the
    packaged ones otherwise."""
    text = str(path_or_name)
    if os.path.isfile(text):
        return text
    bare = text[:-5] if text.endswith(".yaml") else text
    if "/" not in bare and os.sep not in bare:
        packaged = resources.files(package) / f"{bare}.yaml"
        if packaged.is_file():
            return str(packaged)
    raise error(f"{what} {text!r} not found: give a YAML file path or one of the packaged {what}s "
                f"{packaged_names(package)}")


def layout_names():
    """Names of the layouts shipped with the package (without `.yaml`)."""
    return packaged_names("cbtc.track_layouts")


def path_layout_names():
    """Names of the shipped single-path layouts (loops and lines: what the simulator and the zone run on)."""
    return [name for name in layout_names() if not load_track(name).is_network]


def resolve_layout(path_or_name) -> str:
    """A readable file path for a layout file path or a packaged layout name."""
    return resolve_packaged(path_or_name, "cbtc.track_layouts", "layout")


def load_track(path_or_name):
    """Load and validate any layout: a Layout (one path) or a NetworkLayout (sections and switches)."""
    source = resolve_layout(path_or_name)
    try:
        with open(source, encoding="utf-8") as f:
            data = load_with_lines(f)
    except yaml.YAMLError as exc:
        raise LayoutError(f"{source}: not valid YAML: {' '.join(str(exc).split())}; fix the syntax there") from None
    except YamlKeyError as exc:
        raise LayoutError(f"{source}:{exc.line}: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LayoutError(f"{source}: cannot read it as a UTF-8 text file: {exc}") from None
    return layout_from_dict(data, source)


def load_layout(path_or_name, what="this command") -> Layout:
    """Load and validate a single-path layout from a YAML file path or a packaged name such as "itb_square";
    LayoutError for a track network, which `what` cannot run on."""
    return refuse_network(load_track(path_or_name), what)
