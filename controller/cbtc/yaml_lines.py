"""A YAML loader that keeps line numbers: mappings and sequences remember their own line and each key's or item's, so
the readers of layout and scenario files name the line of a bad value. Keys must be words and given once."""

import yaml


class LineMap(dict):
    """A YAML mapping that remembers its own line and the line of each key."""
    line = 0
    lines = None


class LineSeq(list):
    """A YAML sequence that remembers its own line and the line of each item."""
    line = 0
    lines = None


class LineLoader(yaml.SafeLoader):
    pass


class YamlKeyError(ValueError):
    """A key the loader cannot take, at a line."""

    def __init__(self, line, message):
        super().__init__(message)
        self.line = line


def _mapping(loader, node):
    loader.flatten_mapping(node)
    out = LineMap()
    out.line, out.lines = node.start_mark.line + 1, {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if not isinstance(key, (str, int, float, bool)) or key is None:
            raise YamlKeyError(key_node.start_mark.line + 1, f"a key must be a word, got {key!r}")
        if key in out:
            raise YamlKeyError(key_node.start_mark.line + 1, f"key {key!r} is given twice (first on line "
                                                             f"{out.lines[key]}); keep one")
        out[key] = loader.construct_object(value_node, deep=True)
        out.lines[key] = key_node.start_mark.line + 1
    return out


def _sequence(loader, node):
    out = LineSeq(loader.construct_object(child, deep=True) for child in node.value)
    out.line, out.lines = node.start_mark.line + 1, [child.start_mark.line + 1 for child in node.value]
    return out


LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)
LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _sequence)


def load_with_lines(stream):
    """The YAML tree of `stream` with line numbers kept (LineMap, LineSeq); yaml.YAMLError or YamlKeyError."""
    return yaml.load(stream, Loader=LineLoader)   # noqa: S506 (a SafeLoader that keeps line numbers)
