"""Reading a study definition: YAML text to plain values, each with the line it is on.

Only YAML's safe types are read (mappings, lists, text, numbers, true/false, null): the
text is composed into YAML's node tree (``yaml.compose`` with the safe loader, which
builds no object), and each node is turned into a value here, so every value keeps its
line. Numbers are only those written as JSON writes them (``bounded_reading.PlainLoader``):
``0x10``, ``1_0`` or ``+3`` are text, which a number's setting refuses by its name. A
hostile text is refused before it costs anything: past ``MAX_DEFINITION_BYTES``, nested
past ``MAX_DEPTH``, expanding past ``MAX_NODES`` values through aliases (a "billion
laughs"), with a key twice, a number that is not finite, a date that is no date or text
with a NUL character (PostgreSQL cannot store one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import yaml

from studyapp.definitions.errors import DefinitionError
from studyapp.server.uploads.bounded_reading import MAX_DEPTH, PlainLoader

# A definition with a hundred custom paths of a minute each is about this long.
MAX_DEFINITION_BYTES = 4_000_000
MAX_NODES = 500_000
Path = tuple[str | int, ...]
PLAIN_COLLECTIONS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq")


@dataclass
class Located:
    """A definition's values and the line (from 1) of each, keyed by its path of keys and
    list indexes (the line of a mapping's entry is its key's)."""

    value: object
    lines: dict[Path, int] = field(default_factory=dict)

    def line(self, path: Path) -> int | None:
        """The line of ``path``, or of the nearest enclosing value that has one."""
        while path not in self.lines and path:
            path = path[:-1]
        return self.lines.get(path)


class _Reader:
    def __init__(self, source: str) -> None:
        self.source, self.nodes = source, 0
        self.lines: dict[Path, int] = {}
        self.constructor = yaml.constructor.SafeConstructor()

    def fail(self, node: yaml.Node, message: str) -> DefinitionError:
        return DefinitionError(self.source, [(node.start_mark.line + 1, message)])

    def value(self, node: yaml.Node, path: Path) -> object:
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise self.fail(node, f"more than {MAX_NODES:,} values (aliases repeating values?): not a study definition")
        if len(path) > MAX_DEPTH:
            raise self.fail(node, f"nested more than {MAX_DEPTH} levels deep: not a study definition")
        self.lines.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.CollectionNode) and node.tag not in PLAIN_COLLECTIONS:  # !!set, !!python/...
            raise self.fail(node, f"not a plain YAML value (tag {node.tag})")
        if isinstance(node, yaml.MappingNode):
            return self.mapping(node, path)
        if isinstance(node, yaml.SequenceNode):
            return [self.value(item, (*path, i)) for i, item in enumerate(node.value)]
        return self.scalar(node)

    def mapping(self, node: yaml.MappingNode, path: Path) -> dict:
        result: dict = {}
        for key_node, value_node in node.value:
            key = self.scalar(key_node) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, str):
                shown = repr(key_node.value) if isinstance(key_node, yaml.ScalarNode) else "a list or mapping"
                raise self.fail(key_node, f"a key must be a name (text), not {shown}")
            if key in result:
                raise self.fail(key_node, f"{key!r} is given twice")
            self.lines[(*path, key)] = key_node.start_mark.line + 1
            result[key] = self.value(value_node, (*path, key))
        return result

    def scalar(self, node: yaml.ScalarNode) -> object:
        try:
            value = self.constructor.construct_object(node)
        except yaml.constructor.ConstructorError as error:
            raise self.fail(node, f"not a plain YAML value ({error.problem})") from None
        except ValueError as error:  # the form of a date, but no date (February 30th)
            raise self.fail(node, f"{node.value[:40]!r} reads as no value ({error}): quote it if it is text") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(node, f"numbers must be finite, not {node.value}")
        if isinstance(value, str) and "\0" in value:
            raise self.fail(node, "the text holds a NUL character (\\0), which no database stores")
        if value is not None and not isinstance(value, str | int | float | bool):
            raise self.fail(node, f"{node.value!r} reads as a {type(value).__name__}: quote it if it is text")
        return value


def _character(code: int | str) -> str:
    return chr(code) if isinstance(code, int) else code


def read_definition(text: str | bytes, source: str) -> Located:
    """The values of a definition's YAML text and their lines (DefinitionError naming
    ``source`` and the line where the text is no YAML or too large)."""
    if len(text) > MAX_DEFINITION_BYTES:
        raise DefinitionError(source, [(None, f"{len(text) / 1e6:.1f} MB is over the "
                                              f"{MAX_DEFINITION_BYTES / 1e6:g} MB a study definition may be")])
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as error:
            raise DefinitionError(source, [(None, f"not UTF-8 text (byte {error.start})")]) from None
    try:
        root = yaml.compose(text, Loader=PlainLoader)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        raise DefinitionError(source, [(mark.line + 1 if mark else None,
                                        f"not valid YAML: {error.problem or error.context}")]) from None
    except yaml.reader.ReaderError as error:  # a character YAML does not allow (no mark: its position instead)
        raise DefinitionError(source, [(text[:error.position].count("\n") + 1,
                                        f"not valid YAML: the character {_character(error.character)!r} cannot be in "
                                        "a YAML file")]) from None
    except yaml.YAMLError as error:
        raise DefinitionError(source, [(None, f"not valid YAML: {' '.join(str(error).split())}")]) from None
    except RecursionError:  # the composer recurses per level of nesting
        raise DefinitionError(source, [(None, "nested too deeply to be a study definition")]) from None
    if root is None:
        raise DefinitionError(source, [(None, "the file is empty: a study definition is a mapping of its settings")])
    reader = _Reader(source)
    value = reader.value(root, ())
    if not isinstance(value, dict):
        raise DefinitionError(source, [(1, f"a study definition is a mapping of settings, not a "
                                           f"{'list' if isinstance(value, list) else type(value).__name__}")])
    return Located(value, reader.lines)
