"""YAML read as ``yaml.safe_load`` reads it (plain data: no tag builds an object), and
whole: what safe_load lets through is refused with the line.

- A key given twice in one mapping: safe_load keeps the last one silently (a limit
  written twice, the second one wrong, would pass); both lines are named.
- Aliases: at most ``MAX_ALIASES``, and the document, expanded through them, at most
  ``MAX_NODES`` nodes. A few hundred bytes of nested aliases expand to billions of
  nodes in whatever walks the data (the validation, the error's line finder).
- Nesting: at most ``MAX_DEPTH`` levels; PyYAML's composer recurses once per level, and
  20,000 brackets overflowed Python's stack.
- Numbers as YAML 1.2 reads them (its core schema), where PyYAML reads YAML 1.1: a
  number is what it says in decimal (``1e5`` and ``1.0e5`` are numbers, not text). A
  plain value the two versions read as different numbers, or one as a number and the
  other as text, is refused with its line and key rather than guessed: ``045`` (octal
  37 to YAML 1.1, 45 to 1.2), ``0o45``, ``1:30`` (base 60: 90 to 1.1), ``1_000``,
  ``0b101``, ``-0x1F``. A limit read silently as another number is the one outcome
  that must not happen; quoted, each is text. Hexadecimal ``0x1F`` means 31 to both.
- A number is at most ``MAX_NUMBER_CHARS`` characters: Python refuses to convert
  integers of more than 4300 digits with an error about its own internals.
"""

from __future__ import annotations

import math
import re

import yaml
from yaml.composer import ComposerError
from yaml.constructor import ConstructorError

MAX_ALIASES = 1000
MAX_NODES = 100_000
MAX_DEPTH = 64
# no setting needs more; the integers Python converts stop at 4300 digits
MAX_NUMBER_CHARS = 100
_MERGE_TAG = "tag:yaml.org,2002:merge"
INT_TAG = "tag:yaml.org,2002:int"
FLOAT_TAG = "tag:yaml.org,2002:float"
# a plain value YAML 1.1 and YAML 1.2 read differently: refused (number_problem)
AMBIGUOUS_TAG = "tag:labrig,2026:ambiguous-number"

# YAML 1.2's core schema (yaml.org/spec/1.2.2, 10.3.2), with the octal form taken out
_INT_12 = re.compile(r"[-+]?[0-9]+|0x[0-9a-fA-F]+")
_FLOAT_12 = re.compile(
    r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)"
)
_OCTAL_12 = re.compile(r"0o[0-7]+")
_LEADING_ZERO = re.compile(r"[-+]?0[0-9]+")


class NumberError(ConstructorError):
    """A plain value that is no number labrig reads: ``problem`` says why and what to
    write; ``path`` is the key path to it (``limits.max_volume_ml``)."""

    def __init__(self, path: str, problem: str, mark) -> None:
        super().__init__(None, None, problem, mark)
        self.path = path


class BoundedSafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` with the bounds and the duplicate-key check above."""

    def __init__(self, stream) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent, index):
        mark = self.peek_event().start_mark
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise ComposerError(None, None, f"more than {MAX_ALIASES} aliases (*name)", mark)
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise ComposerError(None, None, f"nested more than {MAX_DEPTH} levels deep", mark)
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def resolve(self, kind, value, implicit):
        """YAML 1.2's numbers (module docstring); everything else as PyYAML's."""
        if kind is yaml.ScalarNode and implicit[0]:
            if _LEADING_ZERO.fullmatch(value) or _OCTAL_12.fullmatch(value):
                return AMBIGUOUS_TAG
            if _INT_12.fullmatch(value):
                return INT_TAG
            if _FLOAT_12.fullmatch(value):
                return FLOAT_TAG
        tag = super().resolve(kind, value, implicit)
        # what YAML 1.1 alone reads as a number (1:30, 1_000, 0b101, -0x1F)
        return AMBIGUOUS_TAG if tag in (INT_TAG, FLOAT_TAG) else tag

    def construct_yaml_int(self, node) -> int:
        text = self.construct_scalar(node)
        try:
            return int(text, 16) if text.startswith("0x") else int(text)
        except ValueError:  # an explicit !!int on something else
            raise ConstructorError(None, None, f"{text!r} is no integer", node.start_mark) from None

    def construct_yaml_float(self, node) -> float:
        text = self.construct_scalar(node)
        if text.lstrip("+-").lower() == ".inf":
            return -math.inf if text.startswith("-") else math.inf
        if text.lower() == ".nan":
            return math.nan
        try:
            return float(text)
        except ValueError:  # an explicit !!float on something else
            raise ConstructorError(None, None, f"{text!r} is no number", node.start_mark) from None

    def construct_mapping(self, node, deep=False):
        first_line: dict[tuple[str, str], int] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE_TAG:
                continue
            key = (key_node.tag, key_node.value)
            line = key_node.start_mark.line + 1
            if key in first_line:
                raise ConstructorError(
                    None,
                    None,
                    f"key {key_node.value!r} given twice in one mapping (line "
                    f"{first_line[key]} and line {line}); keep one",
                    key_node.start_mark,
                )
            first_line[key] = line
        return super().construct_mapping(node, deep)


BoundedSafeLoader.add_constructor(INT_TAG, BoundedSafeLoader.construct_yaml_int)
BoundedSafeLoader.add_constructor(FLOAT_TAG, BoundedSafeLoader.construct_yaml_float)


def load_with_nodes(text: str) -> tuple[object, yaml.Node | None]:
    """(data, root node) of a YAML document, parsed once; yaml.YAMLError when it is not
    valid or breaks a bound above (its ``problem_mark`` says where; a ``NumberError``
    also names the key)."""
    loader = BoundedSafeLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None, None
        _check_expanded_size(root)
        _check_numbers(root)
        return loader.construct_document(root), root
    finally:
        loader.dispose()


def number_problem(node: yaml.ScalarNode) -> str | None:
    """Why the plain value of ``node`` is no number labrig reads (None if it is one or
    no number at all)."""
    text = node.value
    if node.tag in (INT_TAG, FLOAT_TAG):
        if len(text) <= MAX_NUMBER_CHARS:
            return None
        return f"a number of {len(text)} characters; numbers here have at most {MAX_NUMBER_CHARS}"
    if node.tag != AMBIGUOUS_TAG:
        return None
    if len(text) > MAX_NUMBER_CHARS:
        return f"a value of {len(text)} characters that YAML 1.1 reads as a number"
    if _OCTAL_12.fullmatch(text):
        return (
            f"{text} is octal {int(text[2:], 8)} to YAML 1.2 and text to YAML 1.1: write "
            f"{int(text[2:], 8)} in decimal, or quote it for text"
        )
    old = yaml.safe_load(text)  # YAML 1.1's reading
    old_text = "text" if isinstance(old, str) else f"{old!r}"
    new = int(text) if _LEADING_ZERO.fullmatch(text) else None
    new_text = "text" if new is None else f"{new}"
    meant = new if new is not None else old
    return (
        f"{text} is {old_text} to YAML 1.1 and {new_text} to YAML 1.2: write {meant!r} "
        "in decimal, or quote it for text"
    )


def _check_numbers(root: yaml.Node) -> None:
    """Refuse, with its key path, the first value that is no number labrig reads."""
    seen: set[int] = set()
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, path = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.ScalarNode):
            problem = number_problem(node)
            if problem is not None:
                raise NumberError(path, problem, node.start_mark)
        elif isinstance(node, yaml.SequenceNode):
            stack += [(child, f"{path}[{i}]") for i, child in enumerate(node.value)][::-1]
        elif isinstance(node, yaml.MappingNode):
            for key, value in reversed(node.value):
                name = key.value if isinstance(key, yaml.ScalarNode) else "?"
                stack.append((value, f"{path}.{name}" if path else str(name)))
                stack.append((key, path))


def _check_expanded_size(root: yaml.Node) -> None:
    """Refuse a document whose aliases expand it beyond MAX_NODES nodes. An alias is the
    node it names, shared, so sizes are counted once per node and the count stays cheap."""
    sizes: dict[int, int] = {}
    inside: set[int] = set()

    def size(node: yaml.Node) -> int:
        known = sizes.get(id(node))
        if known is not None:
            return known
        if id(node) in inside:
            raise ComposerError(None, None, "an alias inside its own anchor", node.start_mark)
        inside.add(id(node))
        total = 1
        if isinstance(node, yaml.SequenceNode):
            total += sum(size(child) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            total += sum(size(key) + size(value) for key, value in node.value)
        if total > MAX_NODES:
            raise ComposerError(
                None,
                None,
                f"expands through its aliases to more than {MAX_NODES} values",
                node.start_mark,
            )
        sizes[id(node)] = total
        inside.discard(id(node))
        return total

    size(root)
