"""YAML from files a user hands us (plant files, scenarios, bag metadata), read within limits.

PyYAML's safe loader builds no objects, but it reads a file of any size, recurses once
per nesting level (20,000 levels end in RecursionError) and shares aliased nodes that a
consumer then walks once per reference (an alias bomb of a few hundred bytes stands for
billions of values). Here the file size, the nesting depth, the number of aliases and
the size of the document with every alias expanded are bounded, and each breach is one
`YamlLimitError` saying which limit and where.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

MAX_BYTES = 1 << 20  # a plant file or scenario is a few kB
MAX_DEPTH = 64
MAX_ALIASES = 1000
MAX_EXPANDED_NODES = 1_000_000  # nodes of the document with every alias expanded


class YamlLimitError(ValueError):
    """The text is not YAML we read: too large, too deep, too many aliases, not text, or not valid."""


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader that counts nesting and aliases while it composes the document."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        mark = self.peek_event().start_mark
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise YamlLimitError(f"more than {MAX_ALIASES} aliases (line {mark.line + 1})")
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise YamlLimitError(f"nested deeper than {MAX_DEPTH} levels (line {mark.line + 1})")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _expanded_size(node: yaml.Node, sizes: dict[int, int]) -> int:
    """Nodes under `node` counting each alias as a full copy (memoised: linear in the composed graph)."""
    key = id(node)
    if key not in sizes:
        if isinstance(node, yaml.MappingNode):
            children = [child for pair in node.value for child in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = node.value
        else:
            children = []
        sizes[key] = min(1 + sum(_expanded_size(child, sizes) for child in children), MAX_EXPANDED_NODES + 1)
    return sizes[key]


def parse_yaml(text: str) -> Any:
    """The document in `text` as plain Python values, within the limits of this module."""
    try:
        loader = _BoundedLoader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            if _expanded_size(node, {}) > MAX_EXPANDED_NODES:
                raise YamlLimitError(f"more than {MAX_EXPANDED_NODES:,} values once its aliases are expanded")
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.YAMLError as error:
        raise YamlLimitError(f"not valid YAML ({' '.join(str(error).split())})") from None


def load_yaml_file(path: str | Path) -> Any:
    """The YAML document in the file at `path`; OSError if it cannot be read, YamlLimitError if it is not
    a text file of at most MAX_BYTES holding YAML within the limits."""
    path = Path(path)
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise YamlLimitError(f"{size:,} bytes, more than the {MAX_BYTES:,} a YAML file may have")
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise YamlLimitError(f"not a text file (byte {error.start} is not UTF-8)") from None
    return parse_yaml(text)
