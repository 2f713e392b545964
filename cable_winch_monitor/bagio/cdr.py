"""Compiled little-endian CDR encoders: a message's nested field mapping straight to bytes.

`encoder(msgtype)` generates, once per type, a function that packs the mapping that
`records.build` would turn into a message object, giving the bytes that rosbags'
`serialize_cdr` gives for that object (on a little-endian host) without building it.
Nested messages are inlined; runs of scalars whose alignment is known when the code is
generated become one `struct` call, and padding is computed at run time only after
strings and sequences, whose lengths vary.

`fixed_encoder` also takes the fields that every message it encodes has alike (the
scene's markers share a dozen empty strings, sequences and constant sub-messages): those
are not looked up but packed when the code is generated, runs of them as one bytes
literal.

`StackedEncoder` encodes many messages of one shape (the same sequence lengths, strings of the
same length in bytes) at once: copies of one message's bytes, the numbers and strings written
into them as numpy columns. A replay encodes a window's per-sample outputs so.
"""
from __future__ import annotations

import copy
import math
from array import array
from collections.abc import Callable, Mapping, Sequence
from functools import cache, lru_cache
from struct import Struct, pack
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from .typestore import knows, typestore

HEADER = b"\x00\x01\x00\x00"  # CDR_LE encapsulation
SCALAR = {"bool": "?", "byte": "b", "char": "B", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H",
          "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d"}
ELEMENT = {**SCALAR, "byte": "B"}  # rosbags packs byte arrays as uint8
SIZE = {name: Struct("<" + code).size for name, code in SCALAR.items()}
ARRAY_CODES = {code for code in "bBhHiIqQfd" if array(code).itemsize == Struct("<" + code).size}

NUMPY_SCALAR = {"bool": "?", "byte": "u1", "char": "u1", "int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2",
                "int32": "<i4", "uint32": "<u4", "int64": "<i8", "uint64": "<u8", "float32": "<f4", "float64": "<f8"}

Encoder = Callable[[Mapping[str, Any]], bytes]
FieldPath = tuple[str | int, ...]  # field names and list indices from a message's top to one of its values


class Layout:
    """Where a generated CDR codec stands: the offset from the end of the header is known modulo
    `base` to be `rem`; scalars whose alignment is known pend as one struct run (`fmt`, with
    their arguments or targets in `pending`) until `flush` emits it."""

    def __init__(self, store: Typestore):
        self.store = store
        self.lines: list[str] = []
        self.structs: dict[str, str] = {}  # struct format -> name in the generated code
        self.fmt = ""
        self.pending: list[str] = []
        self.base, self.rem, self.indent, self.names = 8, 0, 1, 0

    def emit(self, line: str) -> None:
        self.lines.append("    " * self.indent + line)

    def fresh(self) -> str:
        self.names += 1
        return f"v{self.names}"

    def local(self, expr: str) -> str:
        """A new local variable holding `expr`."""
        name = self.fresh()
        self.emit(f"{name} = {expr}")
        return name

    def struct(self) -> str:
        """The name of the pending run's Struct in the generated code."""
        return self.structs.setdefault("<" + self.fmt, f"S{len(self.structs)}")

    def flush(self) -> None:
        """Emit the pending run of scalars."""
        raise NotImplementedError

    def pad(self, size: int) -> str:
        """A statement aligning to `size` bytes at run time."""
        raise NotImplementedError

    def unknown(self, align: int = 1) -> None:
        """After variable-length data: the offset is known only modulo `align`."""
        self.flush()
        self.base, self.rem = align, 0

    def align(self, size: int) -> None:
        if size <= self.base:
            pad = -self.rem % size
            self.fmt += "x" * pad
            self.rem = (self.rem + pad) % self.base
        else:
            self.flush()
            self.emit(self.pad(size))
            self.base, self.rem = size, 0

    def scalar(self, code: str, size: int, item: str, count: int = 1) -> None:
        """`count` values of `size` bytes each, with struct code `code`: `item` is the argument to pack
        or the target to unpack into."""
        self.align(size)
        self.fmt += code if count == 1 else f"{count}{code}"
        self.pending.append(item)
        self.rem = (self.rem + size * count) % self.base


_RUNTIME = object()  # a pending value known only when the encoder runs


class _EncoderSource(Layout):
    """Source of one encoder, from the nested field mapping `v` to the bytearray `out`; `fixed` maps a
    message type to the (partial, nested) field values every message of that type has."""

    def __init__(self, store: Typestore, fixed: Mapping[str, Mapping[str, Any]] | None = None):
        super().__init__(store)
        self.fixed = fixed or {}
        self.known: list[Any] = []  # the pending run's values, _RUNTIME where known only then

    def flush(self) -> None:
        if self.fmt:
            if _RUNTIME in self.known:
                self.emit(f"out += {self.struct()}.pack({', '.join(self.pending)})")
            else:  # every value is fixed: the bytes are
                self.emit(f"out += {Struct('<' + self.fmt).pack(*self.known)!r}")
            self.fmt, self.pending, self.known = "", [], []

    def scalar(self, code: str, size: int, item: str, count: int = 1, value: Any = _RUNTIME) -> None:
        super().scalar(code, size, item, count)
        self.known.append(value)

    def constant(self, node: int, argument: Any, value: Any) -> None:
        """A field (not a message: `message` goes through those) whose value is `value` in every message."""
        if node == Nodetype.BASE and argument[0] == "string":
            data = value.encode() + b"\0"
            self.scalar("I", 4, str(len(data)), value=len(data))
            self.fmt += f"{len(data)}s"
            self.pending.append(repr(data))
            self.known.append(data)
            self.rem = (self.rem + len(data)) % self.base
        elif node == Nodetype.BASE and argument[0] in SCALAR:
            self.scalar(SCALAR[argument[0]], SIZE[argument[0]], f"{_literal(value)}", value=value)
        elif node == Nodetype.SEQUENCE and not len(value):
            self.scalar("I", 4, "0", value=0)  # no elements: no alignment either
        else:
            self.field(node, argument, _literal(value))

    def pad(self, size: int) -> str:
        return f"out += ZEROS[(4 - len(out)) % {size}]"

    def string(self, expr: str) -> None:
        encoded = self.local(f"{expr}.encode()")
        self.scalar("I", 4, f"len({encoded}) + 1")
        self.flush()
        self.emit(f"out += {encoded}")
        self.emit("out.append(0)")
        self.unknown()

    def message(self, msgtype: str, expr: str, fixed: Mapping[str, Any] | None = None) -> None:
        fixed = self.fixed.get(msgtype, {}) if fixed is None else fixed
        argument: Any  # as `node` says: a base type, a message type's name, or an array's (element, length)
        for name, (node, argument) in self.store.fielddefs[msgtype][1]:
            if name in fixed and node == Nodetype.NAME:
                self.message(argument, f"{expr}[{name!r}]", fixed[name])
            elif name in fixed:
                self.constant(node, argument, fixed[name])
            else:
                self.field(node, argument, f"{expr}[{name!r}]")

    def field(self, node: int, argument: Any, expr: str) -> None:
        if node == Nodetype.NAME:
            self.message(argument, expr)
        elif node == Nodetype.BASE:
            self.base_value(argument[0], expr)
        else:
            (inner, inner_argument), length = argument
            value = self.local(expr)
            if node == Nodetype.SEQUENCE:
                self.scalar("I", 4, f"len({value})")
                if inner == Nodetype.BASE and inner_argument[0] == "string":
                    self.flush()
                    self.emit(f"out += strings(tuple({value}))")  # names repeat from message to message
                    self.unknown()
                    return
            elif inner == Nodetype.BASE and inner_argument[0] in ELEMENT:
                self.scalar(ELEMENT[inner_argument[0]], SIZE[inner_argument[0]], f"*{value}", length)
                return
            self.items(inner, inner_argument, value)

    def base_value(self, name: str, expr: str) -> None:
        if name == "string":
            self.string(expr)
        elif name in SCALAR:
            self.scalar(SCALAR[name], SIZE[name], expr)
        else:
            raise TypeError(f"CDR encoder: type {name} is not supported")

    def items(self, inner: int, inner_argument: Any, value: str) -> None:
        """The elements of a sequence (after its count) or of an array of strings or messages."""
        self.flush()
        if inner == Nodetype.BASE and inner_argument[0] in ELEMENT:
            size = SIZE[inner_argument[0]]
            self.emit(f"if len({value}):")
            if size > 4:  # rosbags aligns the elements only when there are any
                self.emit(f"    {self.pad(size)}")
            code = ELEMENT[inner_argument[0]]
            if code in ARRAY_CODES:  # array's machine values are CDR's on a little-endian host
                self.emit(f"    out += array('{code}', {value}).tobytes()")
            else:
                self.emit(f"    out += pack(f'<{{len({value})}}{code}', *{value})")
            self.unknown(min(size, 4))
            return
        item = self.fresh()
        self.emit(f"for {item} in {value}:")
        self.indent += 1
        self.unknown()
        self.field(inner, inner_argument, item)
        self.flush()
        self.indent -= 1
        self.unknown()

    def source(self, msgtype: str) -> str:
        self.message(msgtype, "v")
        self.flush()
        return "\n".join(["def encode(v):", f"    out = bytearray({HEADER!r})", *self.lines, "    return bytes(out)"])


@lru_cache(maxsize=4096)
def strings(values: tuple[str, ...]) -> bytes:
    """The elements of a sequence of strings as CDR, from the 4-aligned offset after its count:
    each length-prefixed, NUL-terminated and padded to 4 bytes before the next."""
    out = bytearray()
    for text in values:
        out += bytes(-len(out) % 4)
        encoded = text.encode()
        out += pack("<I", len(encoded) + 1) + encoded + b"\0"
    return bytes(out)


def _literal(value: Any) -> str:
    """Python source giving `value` (a number, string or nested mapping or list of them)."""
    if isinstance(value, float) and not math.isfinite(value):
        return f"float({str(value)!r})"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{key!r}: {_literal(item)}" for key, item in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_literal(item) for item in value) + "]"
    return repr(value)


@cache
def encoder(msgtype: str, store: Typestore | None = None) -> Encoder:
    """The compiled encoder of `msgtype` (values as for `records.build`)."""
    return fixed_encoder(msgtype, {}, store)


def fixed_encoder(msgtype: str, fixed: Mapping[str, Mapping[str, Any]], store: Typestore | None = None) -> Encoder:
    """The compiled encoder of `msgtype` for messages whose fields in `fixed` (by message type: a partial
    nested mapping of that type's fields) always hold the values given there; those are not read from the
    values encoded. Gives the bytes of `encoder(msgtype)` for such messages."""
    store = store or typestore()
    knows(store, msgtype)
    generator = _EncoderSource(store, fixed)
    source = generator.source(msgtype)
    namespace: dict[str, Any] = {"pack": pack, "array": array, "strings": strings,
                                 "ZEROS": tuple(bytes(n) for n in range(8))}
    namespace.update({name: Struct(fmt) for fmt, name in generator.structs.items()})
    exec(compile(source, f"<cdr encoder {msgtype}>", "exec"), namespace)
    return namespace["encode"]


class StackedEncoder:
    """Many messages of `msgtype` encoded at once: each the nested field mapping `template` (as for `encoder`)
    but for the scalars and strings at `columns`, which vary from message to message (a string keeping its
    length in bytes); its sequence lengths are every message's. The bytes are `encoder(msgtype)`'s: the
    template is encoded once by it, and each column's place is read off those bytes (where encoding that
    value changed moves them), so the layout is the compiled encoder's own; `encode` writes the columns of n
    messages into n copies of the template."""

    def __init__(self, msgtype: str, template: Mapping[str, Any], columns: Sequence[FieldPath],
                 store: Typestore | None = None):
        store = store or typestore()
        encode = encoder(msgtype, store)
        kinds = [_base_type(store, msgtype, path) for path in columns]
        sizes = [len(_at(template, path).encode()) if kind == "string" else 0 for path, kind in zip(columns, kinds)]
        formats = [np.dtype(f"S{size}" if kind == "string" else NUMPY_SCALAR[kind]) for kind, size in zip(kinds, sizes)]
        zeroed = _replaced(template, {path: "a" * size if kind == "string" else 0
                                      for path, kind, size in zip(columns, kinds, sizes)})
        base = encode(zeroed)
        self.used = [dtype.itemsize > 0 for dtype in formats]  # an empty string writes nothing
        offsets = []
        for path, kind, dtype in zip(columns, kinds, formats):
            if not dtype.itemsize:
                continue
            probe = "b" * dtype.itemsize if kind == "string" else np.frombuffer(
                b"\x01" if dtype.kind == "b" else b"\x11" * dtype.itemsize, dtype)[0].item()
            probed = encode(_replaced(zeroed, {path: probe}))
            moved = [k for k, (a, b) in enumerate(zip(base, probed)) if a != b]
            if len(probed) != len(base) or moved != list(range(moved[0], moved[0] + dtype.itemsize)):
                raise ValueError(f"{msgtype}: the field {path} does not keep its place from message to message")
            offsets.append(moved[0])
        kept = [dtype for dtype in formats if dtype.itemsize]
        self.template = np.frombuffer(base, np.uint8)
        self.dtype = np.dtype({"names": [f"c{k}" for k in range(len(kept))], "formats": kept, "offsets": offsets,
                               "itemsize": len(base)})

    def encode(self, *columns: Any) -> list[bytes]:
        """The messages whose values are `columns` (for each of the constructor's, in order, n numbers or n
        strings' bytes of its length)."""
        count = len(columns[0]) if columns else 0
        buffer = np.tile(self.template, count)
        rows = buffer.view(self.dtype)
        for name, column in zip(self.dtype.names or (), (c for c, used in zip(columns, self.used) if used)):
            rows[name] = column
        data, size = buffer.tobytes(), self.dtype.itemsize
        return [data[start:start + size] for start in range(0, count * size, size)]


def _base_type(store: Typestore, msgtype: str, path: FieldPath) -> str:
    """The base type of the number or string at `path` in a message of `msgtype` (TypeError where it holds
    neither)."""
    node: int = Nodetype.NAME
    argument: Any = msgtype  # as `node` says: a message type's name, a base type, an array's (element, length)
    for step in path:
        if isinstance(step, int) and node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (node, argument), _ = argument
        elif isinstance(step, str) and node == Nodetype.NAME:
            node, argument = dict(store.fielddefs[argument][1])[step]
        else:
            raise TypeError(f"{msgtype}: no field at {path}")
    if node != Nodetype.BASE or (argument[0] not in NUMPY_SCALAR and argument[0] != "string"):
        raise TypeError(f"{msgtype}: {path} is neither a number nor a string")
    return argument[0]


def _at(values: Any, path: FieldPath) -> Any:
    """The value at `path` in nested field values."""
    for step in path:
        values = values[step]
    return values


def _replaced(values: Mapping[str, Any], changes: Mapping[FieldPath, Any]) -> Any:
    """Nested field values with the values at the paths of `changes` set as it says: the mappings and lists
    along those paths copied, the rest shared with `values`, which is left as it was (a deep copy of the
    template for each of a message's columns was most of what a new shape's encoder took to make)."""
    out: Any = copy.copy(values)
    copied: dict[FieldPath, Any] = {(): out}  # each container copied so far, by its path
    for path, value in changes.items():
        holder = out
        for depth in range(1, len(path)):
            inner = copied.get(path[:depth])
            if inner is None:
                inner = copied[path[:depth]] = copy.copy(holder[path[depth - 1]])
                holder[path[depth - 1]] = inner
            holder = inner
        holder[path[-1]] = value
    return out
