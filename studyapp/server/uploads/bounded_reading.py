"""JSON and YAML that come from outside (bundles, definitions), read within bounds.

A parser builds every value before anyone can look at it, and its cost is not the file's
size: ``[{},{},...]`` of 20 MB becomes seven million dictionaries (about 900 MB), and a
few thousand brackets exhaust the parser's stack. So a JSON text is measured first, at
the speed of ``str.count`` and ``re``, without building anything: its size, how deep its
brackets nest (``MAX_DEPTH``) and how many values it holds (``MAX_ITEMS``); only a text
within all three is parsed. Numbers must be finite, and an integer of more than
``MAX_DIGITS`` digits is refused rather than converted (which takes time quadratic in its length).

YAML is read with ``PlainLoader``: the safe loader, whose numbers are only what JSON
writes. YAML 1.1 reads ``0x10`` as 16, ``010`` as 8, ``1_0`` as 10, ``1:30`` as 90 and
``+3`` as 3; here they stay text, which the field's own check then refuses by name.
``yaml_value`` reads a YAML text within the same bounds: its node tree (which builds no
object) is measured, counting a value each time an alias repeats it, before any value is built.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import yaml

MAX_DEPTH = 20  # a bundle's records and a definition nest at most about 8 levels
MAX_ITEMS = 2_000_000  # values; a rating with its page is 20 of them in a bundle's participants.json
MAX_DIGITS = 40  # of an integer; no field stores more than 20

_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")
_INNERMOST = re.compile(r"\[\]|\{\}")


class ReadRefused(ValueError):
    """A text that is not read; the message names the file and the bound or the problem."""


def read_bytes(path: Path, name: str, limit: int) -> bytes:
    """The file's bytes, refused by its size before any of it is read when it is over ``limit``."""
    size = path.stat().st_size
    if size > limit:
        raise ReadRefused(f"{name}: {size / 1e6:.3g} MB, over the {limit / 1e6:g} MB such a file may be")
    with path.open("rb") as stream:
        data = stream.read(limit + 1)  # a file that grew since: still never more than the limit
    if len(data) > limit:
        raise ReadRefused(f"{name}: over the {limit / 1e6:g} MB such a file may be")
    return data


def utf8_text(data: bytes, name: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ReadRefused(f"{name}: not UTF-8 text ({error})") from None


def _measured(text: str, name: str) -> None:
    """Refuse a JSON text nested past ``MAX_DEPTH`` or holding more than ``MAX_ITEMS`` values.

    Outside its strings, every value of a JSON text but the first of each array or object
    follows a comma, so commas and opening brackets bound the count of values. Removing
    the innermost pairs of brackets once per level gives the depth, without recursion."""
    bare = _STRING.sub("", text)
    items = bare.count(",") + bare.count("[") + bare.count("{") + 1
    if items > MAX_ITEMS:
        raise ReadRefused(f"{name}: holds more than {MAX_ITEMS:,} values, more than a study's records hold")
    brackets = _NOT_BRACKET.sub("", bare)
    for _ in range(MAX_DEPTH):
        brackets, removed = _INNERMOST.subn("", brackets)
        if not brackets or not removed:  # all matched, or brackets that do not match: the parser says where
            return
    if _INNERMOST.search(brackets):
        raise ReadRefused(f"{name}: nested more than {MAX_DEPTH} levels deep, deeper than a study's records")


def finite_float(text: str) -> float:
    """The float of a JSON number's text; ValueError for one too large to hold (an infinity)."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:40]} is too large to hold")
    return value


def _refused_constant(text: str) -> float:
    raise ValueError(f"{text} is no number JSON has")


def _whole(text: str) -> int:
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def json_value(data: bytes, name: str, limit: int) -> object:
    """The value of the JSON text ``data`` (ReadRefused naming ``name`` and what is wrong:
    over ``limit`` bytes, not UTF-8, nested or holding too much, not JSON, a number that is not finite)."""
    if len(data) > limit:
        raise ReadRefused(f"{name}: {len(data) / 1e6:.3g} MB, over the {limit / 1e6:g} MB such a file may be")
    text = utf8_text(data, name)
    _measured(text, name)
    try:
        return json.loads(text, parse_float=finite_float, parse_int=_whole, parse_constant=_refused_constant)
    except json.JSONDecodeError as error:
        raise ReadRefused(f"{name}: not JSON ({error})") from None
    except ValueError as error:  # a NaN, an infinity, an integer of thousands of digits
        raise ReadRefused(f"{name}: not JSON a study holds ({error})") from None
    except RecursionError:  # brackets that do not match, nested deeply: the measure leaves them to the parser
        raise ReadRefused(f"{name}: nested too deeply to read") from None


class PlainLoader(yaml.SafeLoader):
    """The safe loader, reading as numbers only what JSON writes as numbers (and YAML's
    ``.inf`` and ``.nan``, which the reader refuses by name); YAML 1.1's other forms of
    numbers (hexadecimal, octal, underscores, sexagesimal, a leading ``+`` or zero) are
    text, and so is an integer of more than ``MAX_DIGITS`` digits (which Python refuses to convert)."""


PlainLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in ("tag:yaml.org,2002:int",
                                                                     "tag:yaml.org,2002:float")]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
PlainLoader.add_implicit_resolver("tag:yaml.org,2002:int", re.compile(rf"^-?(?:0|[1-9][0-9]{{0,{MAX_DIGITS - 1}}})$"),
                                  list("-0123456789"))
PlainLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^(?:-?(?:0|[1-9][0-9]*)(?:\.[0-9]+(?:[eE][-+]?[0-9]+)?|[eE][-+]?[0-9]+)"
               r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+0123456789."))


def _measured_nodes(root: yaml.Node, name: str) -> None:
    """Refuse a YAML node tree nested past ``MAX_DEPTH`` or holding more than ``MAX_ITEMS``
    values, an alias counting as many values as it repeats (a "billion laughs"), without recursion."""
    items, pending = 0, [(root, 0)]
    while pending:
        node, depth = pending.pop()
        items += 1
        if items > MAX_ITEMS:
            raise ReadRefused(f"{name}: holds more than {MAX_ITEMS:,} values (aliases repeating values?)")
        if depth > MAX_DEPTH:
            raise ReadRefused(f"{name}: nested more than {MAX_DEPTH} levels deep, deeper than a study's records")
        if isinstance(node, yaml.SequenceNode):
            pending.extend((item, depth + 1) for item in node.value)
        elif isinstance(node, yaml.MappingNode):
            pending.extend((part, depth + 1) for pair in node.value for part in pair)


def yaml_value(data: bytes, name: str, limit: int) -> object:
    """The value of the YAML text ``data`` read with ``PlainLoader`` (ReadRefused naming ``name``
    and what is wrong: over ``limit`` bytes, not UTF-8, nested or holding too much, not YAML,
    a value of no safe type, a number that is not finite)."""
    if len(data) > limit:
        raise ReadRefused(f"{name}: {len(data) / 1e6:.3g} MB, over the {limit / 1e6:g} MB such a file may be")
    text = utf8_text(data, name)
    loader = PlainLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None
        _measured_nodes(root, name)
        value = loader.construct_document(root)
    except yaml.YAMLError as error:  # no YAML, or a tag of no safe type (!!python/object)
        raise ReadRefused(f"{name}: not YAML a study holds ({' '.join(str(error).split())})") from None
    except ValueError as error:  # the form of a date, but no date (February 30th)
        raise ReadRefused(f"{name}: not YAML a study holds ({error})") from None
    except RecursionError:  # the composer recurses per level, before the tree can be measured
        raise ReadRefused(f"{name}: nested too deeply to read") from None
    finally:
        loader.dispose()
    _finite_numbers(value, name)
    return value


def _finite_numbers(value: object, name: str) -> None:
    """Refuse YAML's ``.inf`` and ``.nan`` anywhere in ``value`` (already measured: no deeper than ``MAX_DEPTH``)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ReadRefused(f"{name}: not YAML a study holds (the number {value} is not finite)")
    for item in value.values() if isinstance(value, dict) else value if isinstance(value, list) else ():
        _finite_numbers(item, name)


__all__ = ["MAX_DEPTH", "MAX_ITEMS", "PlainLoader", "ReadRefused", "finite_float", "json_value", "read_bytes", "utf8_text",
           "yaml_value"]
