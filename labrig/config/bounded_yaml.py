"""YAML read as ``yaml.safe_load`` reads it (plain data: no tag builds an object), and
whole: what safe_load lets through is refused with the line.

- A key given twice in one mapping: safe_load keeps the last one silently (a limit
  written twice, the second one wrong, would pass); both lines are named.
- Aliases: at most ``MAX_ALIASES``, and the document, expanded through them, at most
  ``MAX_NODES`` nodes. A few hundred bytes of nested aliases expand to billions of
  nodes in whatever walks the data (the validation, the error's line finder).
- Nesting: at most ``MAX_DEPTH`` levels; PyYAML's composer recurses once per level, and
  20,000 brackets overflowed Python's stack.
"""

from __future__ import annotations

import yaml
from yaml.composer import ComposerError
from yaml.constructor import ConstructorError

MAX_ALIASES = 1000
MAX_NODES = 100_000
MAX_DEPTH = 64
_MERGE_TAG = "tag:yaml.org,2002:merge"


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


def load_with_nodes(text: str) -> tuple[object, yaml.Node | None]:
    """(data, root node) of a YAML document, parsed once; yaml.YAMLError when it is not
    valid or breaks a bound above (its ``problem_mark`` says where)."""
    loader = BoundedSafeLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None, None
        _check_expanded_size(root)
        return loader.construct_document(root), root
    finally:
        loader.dispose()


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
