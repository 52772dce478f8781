"""Check a VTK XML file's declared sizes before VTK's reader trusts them.

VTK's XML readers allocate what a file declares (``NumberOfPoints``, ``NumberOfTuples``, the
last cell offset, a compressed block header) before they look at the data; a declared size of
2^50 bytes makes the C++ allocator throw ``std::bad_alloc``, which aborts the whole process
(exit 134) and no Python code can catch.  :func:`check_vtk_xml` reads the XML part and every
array's header (ascii, inline base64, appended raw and appended base64; uncompressed or
compressed with zlib, LZ4 or LZMA; UInt32 or UInt64 headers) without VTK and refuses a file
where

* an array declares more values than its data holds (ascii tokens, the bytes after a binary
  header, the blocks of a compressed one),
* a compressed block claims to expand more than its compressor can (zlib: 1032 times, LZ4: 255
  times, LZMA: 7000 times, plus a little),
* a cell offset array ends beyond the connectivity stored beside it, or
* what the reader would allocate in all exceeds the memory budget
  (:func:`filters.memory.memory_limit`: 80 % of the available memory, or ``BLOBFLOW_MAX_MEMORY``).

Everything is read through a memory map of the file: checking costs no copy of it. What the
checker does not understand (XML comments, entities, another dataset type) is refused rather
than passed on.
"""

from __future__ import annotations

import base64
import binascii
import lzma
import mmap
import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from filters.memory import format_bytes, memory_limit

__all__ = ["UnsafeFileError", "check_vtk_xml", "XML_SUFFIXES"]

#: Suffixes of the single-dataset VTK XML files the checker knows.
XML_SUFFIXES = (".vtp", ".vtu", ".vti", ".vts", ".vtr")

_TYPE_SIZES = {"Int8": 1, "UInt8": 1, "Char": 1, "Int16": 2, "UInt16": 2, "Int32": 4,
               "UInt32": 4, "Float32": 4, "Int64": 8, "UInt64": 8, "Float64": 8,
               "IdType": 8, "String": 1, "Bit": 1}
_INT_FORMATS = {("Int8", 1): "b", ("UInt8", 1): "B", ("Int16", 2): "h", ("UInt16", 2): "H",
                ("Int32", 4): "i", ("UInt32", 4): "I", ("Int64", 8): "q", ("UInt64", 8): "Q",
                ("IdType", 8): "q"}
#: Largest expansion of one compressed block, by compressor (deflate's limit is 1032:1; LZ4's
#: block format 255:1; LZMA measured at about 6900:1 on zeros), and the slack on top of it.
_EXPANSION = {"vtkZLibDataCompressor": 1032, "vtkLZ4DataCompressor": 256,
              "vtkLZMADataCompressor": 8000}
_SLACK = 4096
#: What VTK spends per array besides its values (object, name, information), counted in the
#: budget so that a million tiny arrays are refused too.
_ARRAY_OVERHEAD = 1024
_DATASETS = ("PolyData", "UnstructuredGrid", "ImageData", "StructuredGrid", "RectilinearGrid")
_CELL_GROUPS = ("Verts", "Lines", "Strips", "Polys", "Cells")

_TAG = re.compile(rb"<(/?)([A-Za-z_][\w.:-]*)((?:[^>\"']|\"[^\"]*\"|'[^']*')*?)(/?)>")
_ATTR = re.compile(rb"([A-Za-z_][\w.:-]*)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")
_FORBIDDEN = re.compile(rb"<!--|<!\[CDATA\[|<!DOCTYPE|<!ENTITY|&[A-Za-z_][\w.-]*;")
_WS = re.compile(rb"\s+")


class UnsafeFileError(ValueError):
    """A VTK XML file declares sizes its data does not hold, or more than the memory budget."""


@dataclass
class _Array:
    name: str
    parent: str
    dtype: str
    size: int
    components: int
    tuples: int | None
    fmt: str
    offset: int | None = None
    content: tuple[int, int] | None = None  # inline text span
    available: int = 0  # values the data holds
    buffer: int = 0  # largest decompression buffer (bytes)
    last_value: int | None = None  # of an offsets array


@dataclass
class _Layout:
    kind: str = ""
    word: int = 4
    order: str = "<"
    compressor: str | None = None
    points: int = 0
    cells: dict = field(default_factory=dict)
    arrays: list = field(default_factory=list)
    appended: tuple[int, str] | None = None  # (base position, encoding)
    appended_end: int = 0
    whole: int | None = None  # points of the WholeExtent


def _attrs(text: bytes) -> dict[str, str]:
    return {m.group(1).decode("ascii", "replace"):
            (m.group(2) if m.group(2) is not None else m.group(3)).decode("utf-8", "replace")
            for m in _ATTR.finditer(text)}


class _Checker:
    def __init__(self, path: Path, data, budget: int):
        self.path = path
        self.data = data
        self.size = len(data)
        self.budget = budget

    def fail(self, message: str):
        raise UnsafeFileError(f"{self.path} is not a VTK XML file that can be read safely: "
                              f"{message}")

    def count(self, value: str | None, what: str, default: int | None = 0) -> int | None:
        if value is None:
            return default
        text = value.strip()
        if not re.fullmatch(r"\+?\d{1,30}", text):
            self.fail(f"{what} must be a non-negative integer, got {value[:40]!r}")
        return int(text)

    # -- the XML part ------------------------------------------------------------------------
    def parse(self) -> _Layout:
        data = self.data
        marker = re.search(rb"<AppendedData\b([^>]*)>", data)
        xml_end = marker.start() if marker else self.size
        if _FORBIDDEN.search(data, 0, xml_end):
            self.fail("it holds XML comments, CDATA, a DOCTYPE or entities, which VTK's "
                      "writers never write")
        layout = _Layout()
        if marker is not None:
            encoding = _attrs(marker.group(1)).get("encoding", "raw")
            if encoding not in ("raw", "base64"):
                self.fail(f"unknown AppendedData encoding {encoding!r}")
            underscore = data.find(b"_", marker.end())
            if underscore < 0 or data[marker.end():underscore].strip():
                self.fail("the AppendedData section does not start with '_'")
            layout.appended = (underscore + 1, encoding)
            end = data.rfind(b"</AppendedData>") if encoding == "base64" else -1
            layout.appended_end = end if end > underscore else self.size
        stack: list[str] = []
        current: _Array | None = None
        seen_root = False
        for match in _TAG.finditer(data, 0, xml_end):
            closing, name = match.group(1), match.group(2).decode("ascii", "replace")
            attrs = _attrs(match.group(3))
            empty = bool(match.group(4)) or match.group(3).rstrip().endswith(b"/")
            if closing:
                if name == "DataArray" and current is not None:
                    current = None
                if stack and stack[-1] == name:
                    stack.pop()
                continue
            if name == "VTKFile":
                seen_root = True
                self.root(layout, attrs)
            elif name == "Piece":
                self.piece(layout, attrs)
            elif name in _DATASETS and name == layout.kind and "WholeExtent" in attrs:
                layout.whole = self.extent(attrs["WholeExtent"])[0]
            elif name == "DataArray" or name == "Array":
                parent = stack[-1] if stack else ""
                current = self.array(layout, attrs, parent)
                if current.fmt != "appended" and not empty:
                    start = match.end()
                    stop = data.find(b"<", start, xml_end)
                    current.content = (start, xml_end if stop < 0 else stop)
            if not empty:
                stack.append(name)
        if not seen_root or not layout.kind:
            self.fail("no <VTKFile type=...> element")
        if layout.whole is not None and layout.whole != layout.points:
            self.fail(f"its pieces hold {layout.points} points, its WholeExtent {layout.whole}")
        return layout

    def root(self, layout: _Layout, attrs: dict) -> None:
        layout.kind = attrs.get("type", "")
        if layout.kind not in _DATASETS:
            self.fail(f"type {layout.kind!r} is not one dataset ({', '.join(_DATASETS)})")
        header = attrs.get("header_type", "UInt32")
        if header not in ("UInt32", "UInt64"):
            self.fail(f"unknown header_type {header!r}")
        layout.word = 4 if header == "UInt32" else 8
        order = attrs.get("byte_order", "LittleEndian")
        if order not in ("LittleEndian", "BigEndian"):
            self.fail(f"unknown byte_order {order!r}")
        layout.order = "<" if order == "LittleEndian" else ">"
        compressor = attrs.get("compressor")
        if compressor is not None and compressor not in _EXPANSION:
            self.fail(f"unknown compressor {compressor!r}")
        layout.compressor = compressor

    def extent(self, text: str) -> tuple[int, int]:
        """Points and cells of an ``x0 x1 y0 y1 z0 z1`` extent."""
        parts = text.split()
        if len(parts) != 6 or not all(re.fullmatch(r"[+-]?\d{1,30}", p) for p in parts):
            self.fail(f"an extent must be six integers, got {text[:60]!r}")
        values = [int(p) for p in parts]
        points = cells = 1
        for lo, hi in zip(values[0::2], values[1::2], strict=False):
            if hi < lo:
                self.fail(f"extent {text!r} is empty or reversed")
            points *= hi - lo + 1
            cells *= max(hi - lo, 1)
        return points, cells

    def piece(self, layout: _Layout, attrs: dict) -> None:
        if "Extent" in attrs:
            points, cells = self.extent(attrs["Extent"])
            layout.points += points
            layout.cells["Cells"] = layout.cells.get("Cells", 0) + cells
            return
        layout.points += self.count(attrs.get("NumberOfPoints"), "NumberOfPoints")
        if layout.kind == "PolyData":
            for group in ("Verts", "Lines", "Strips", "Polys"):
                layout.cells[group] = (layout.cells.get(group, 0)
                                       + self.count(attrs.get(f"NumberOf{group}"),
                                                    f"NumberOf{group}"))
        else:
            layout.cells["Cells"] = (layout.cells.get("Cells", 0)
                                     + self.count(attrs.get("NumberOfCells"), "NumberOfCells"))

    def array(self, layout: _Layout, attrs: dict, parent: str) -> _Array:
        name = attrs.get("Name", "")
        dtype = attrs.get("type", "")
        if dtype not in _TYPE_SIZES:
            self.fail(f"array {name!r} has unknown type {dtype!r}")
        fmt = attrs.get("format", "ascii")
        if fmt not in ("ascii", "binary", "appended"):
            self.fail(f"array {name!r} has unknown format {fmt!r}")
        components = self.count(attrs.get("NumberOfComponents"), "NumberOfComponents", 1)
        if components < 1:
            self.fail(f"array {name!r} has NumberOfComponents = 0")
        tuples = self.count(attrs.get("NumberOfTuples"), "NumberOfTuples", None)
        array = _Array(name, parent, dtype, _TYPE_SIZES[dtype], components, tuples, fmt)
        if fmt == "appended":
            if layout.appended is None:
                self.fail(f"array {name!r} is appended but the file has no AppendedData")
            array.offset = self.count(attrs.get("offset"), "offset", None)
            if array.offset is None:
                self.fail(f"appended array {name!r} has no offset")
        layout.arrays.append(array)
        return array

    # -- the data of each array --------------------------------------------------------------
    def measure(self, layout: _Layout, array: _Array) -> None:
        """Fill ``available`` (values held), ``buffer`` and, for offsets, ``last_value``."""
        if array.fmt == "ascii":
            start, stop = array.content or (0, 0)
            array.available = _count_tokens(self.data, start, stop)
            if array.name.endswith("offsets") and array.available:
                last = _last_token(self.data, start, stop)
                try:
                    array.last_value = int(last)
                except ValueError:
                    self.fail(f"offsets array {array.name!r} ends in {last[:20]!r}")
            return
        if array.fmt == "binary":
            start, stop = array.content or (0, 0)
            while start < stop and self.data[start:start + 1].isspace():
                start += 1
            while stop > start and self.data[stop - 1:stop].isspace():
                stop -= 1
            if _WS.search(self.data, start, stop):  # wrapped lines: read without the breaks
                text = _WS.sub(b"", self.data[start:stop])
                reader = _Base64(self, text, 0, len(text), array.name)
            else:  # as VTK writes it: read in place, no copy
                reader = _Base64(self, self.data, start, stop, array.name)
        elif layout.appended[1] == "raw":
            reader = _Raw(self, layout.appended[0] + array.offset, self.size, array.name)
        else:
            reader = _Base64(self, self.data, layout.appended[0] + array.offset,
                             layout.appended_end, array.name)
        word, order = layout.word, layout.order
        fmt = order + ("I" if word == 4 else "Q")
        if layout.compressor is None:
            (nbytes,) = struct.unpack(fmt, reader.header(word))
            if nbytes > reader.remaining():
                self.fail(f"array {array.name!r} claims {format_bytes(nbytes)} of data, more "
                          f"than the file holds after it ({format_bytes(reader.remaining())})")
            array.available = nbytes // array.size
            array.buffer = nbytes
            if array.name.endswith("offsets") and nbytes >= array.size:
                array.last_value = self.last_int(array, reader.read(nbytes))
            return
        blocks, block_size, last_size = struct.unpack(order + fmt[1] * 3, reader.header(3 * word))
        if blocks * word > reader.remaining():
            self.fail(f"array {array.name!r} claims {blocks} compressed blocks, more than the "
                      f"file holds")
        sizes = struct.unpack(order + fmt[1] * blocks, reader.header(blocks * word, more=True))
        stored = sum(sizes)
        if stored > reader.remaining():
            self.fail(f"array {array.name!r}'s compressed blocks ({format_bytes(stored)}) run "
                      f"past the end of the file")
        limit = _EXPANSION[layout.compressor]
        expanded = [block_size] * blocks
        if blocks and last_size:
            expanded[-1] = last_size
        for claimed, size in zip(expanded, sizes, strict=False):
            if claimed > limit * size + _SLACK:
                self.fail(f"array {array.name!r} has a compressed block of {format_bytes(size)} "
                          f"claiming {format_bytes(claimed)}: more than "
                          f"{layout.compressor[3:-14]} can expand ({limit} times)")
        total = sum(expanded)
        array.available = total // array.size
        array.buffer = max(expanded, default=0) + max(sizes, default=0)
        if array.name.endswith("offsets") and total >= array.size and blocks:
            compressed = reader.read(stored)
            first = sum(sizes[:-1])
            block = _decompress(self, layout.compressor, compressed[first:], expanded[-1],
                                array.name)
            if len(block) < array.size:
                self.fail(f"array {array.name!r}'s last block decompresses to "
                          f"{len(block)} bytes")
            tail = block[: len(block) - len(block) % array.size]
            array.last_value = self.last_int(array, tail)

    def last_int(self, array: _Array, data: bytes) -> int:
        code = _INT_FORMATS.get((array.dtype, array.size))
        if code is None:
            self.fail(f"offsets array {array.name!r} has the non-integer type {array.dtype}")
        order = "<" if self.layout.order == "<" else ">"
        usable = len(data) - len(data) % array.size
        if usable < array.size:
            self.fail(f"offsets array {array.name!r} holds no whole value")
        return struct.unpack(order + code, data[usable - array.size:usable])[0]

    # -- the whole file ----------------------------------------------------------------------
    def run(self) -> None:
        self.layout = layout = self.parse()
        for array in layout.arrays:
            self.measure(layout, array)
        by_parent: dict[str, list[_Array]] = {}
        for array in layout.arrays:
            by_parent.setdefault(array.parent, []).append(array)
        total = self.size
        largest_buffer = 0
        # offsets first: the connectivity's size is their last value
        for array in sorted(layout.arrays, key=lambda a: a.name != "offsets"):
            declared, exact = self.declared(layout, array, by_parent.get(array.parent, []))
            values = declared * array.components
            if array.dtype == "Bit":
                values = (values + 7) // 8
            if values > array.available:
                self.fail(f"array {array.name!r} declares {declared} tuples of "
                          f"{array.components} ({format_bytes(values * array.size)}), more "
                          f"than its data holds ({array.available} values)")
            if exact and array.dtype != "String" and array.available not in exact:
                self.fail(f"array {array.name!r} declares {declared} tuples of "
                          f"{array.components} but its data holds {array.available} values")
            total += values * array.size + _ARRAY_OVERHEAD
            largest_buffer = max(largest_buffer, array.buffer)
        total += largest_buffer
        if total > self.budget:
            self.fail(f"reading it needs about {format_bytes(total)}, more than the memory "
                      f"budget of {format_bytes(self.budget)}")

    def declared(self, layout: _Layout, array: _Array,
                 siblings: list[_Array]) -> tuple[int, tuple[int, ...]]:
        """Tuples the reader allocates for ``array``, and the value counts its data may hold
        (empty where the file does not say)."""
        parent, name, comps = array.parent, array.name, array.components
        known = None
        if parent in ("PointData", "Points"):
            known = layout.points
        elif parent == "CellData":
            known = sum(layout.cells.values())
        elif parent in _CELL_GROUPS:
            cells = layout.cells.get(parent, 0)
            if name == "offsets":
                last = array.last_value
                holds = max((a.available // a.components for a in siblings
                             if a.name == "connectivity"), default=0)
                if last is not None and not 0 <= last <= holds:
                    self.fail(f"{parent} offsets end at {last}, outside the {holds} "
                              f"connectivity values stored beside them")
                if array.tuples is None:  # n offsets (format 1.0) or n + 1 (from 0)
                    return cells, (cells * comps, (cells + 1) * comps)
                known = array.tuples
            elif name == "connectivity":
                ends = [a.last_value for a in siblings
                        if a.name == "offsets" and a.last_value is not None]
                known = max(ends, default=0)
            elif name == "types":
                known = cells
        if array.tuples is not None:
            known = array.tuples if known is None else max(known, array.tuples)
        if known is None:  # not said by the file: bounded by its data only
            return 0, ()
        return known, (known * comps,) if array.dtype != "Bit" else ((known * comps + 7) // 8,)


class _Raw:
    """Reads a binary header and data at ``pos`` in the raw appended section."""

    def __init__(self, checker: _Checker, pos: int, end: int, name: str):
        self.checker, self.pos, self.end, self.name = checker, pos, end, name

    def remaining(self) -> int:
        return max(self.end - self.pos, 0)

    def header(self, n: int, more: bool = False) -> bytes:
        if self.pos + n > self.end:
            self.checker.fail(f"array {self.name!r}'s header at byte {self.pos} runs past the "
                              f"end of the file")
        out = bytes(self.checker.data[self.pos:self.pos + n])
        self.pos += n
        return out

    def read(self, n: int) -> bytes:
        return bytes(self.checker.data[self.pos:self.pos + n])


class _Base64:
    """Reads a base64 header and data starting at character ``pos``.

    A compressed array's header is one base64 block and its data another; an uncompressed
    array's length word and data are one block."""

    def __init__(self, checker: _Checker, text, pos: int, end: int, name: str):
        self.checker, self.text, self.start, self.end, self.name = checker, text, pos, end, name
        self.compressed = checker.layout.compressor is not None
        self.used = 0  # header bytes read

    def _decode(self, start: int, nbytes: int) -> bytes:
        chars = 4 * -(-nbytes // 3)
        if start + chars > self.end:
            self.checker.fail(f"array {self.name!r}'s base64 data runs past the end of the "
                              f"file")
        try:
            return base64.b64decode(bytes(self.text[start:start + chars]), validate=True)
        except (binascii.Error, ValueError):
            self.checker.fail(f"array {self.name!r} holds invalid base64")

    def _data_start(self) -> int:
        return self.start + 4 * -(-self.used // 3)

    def remaining(self) -> int:
        """Bytes the rest of the base64 text can hold after what was read."""
        if self.compressed:
            return max(self.end - self._data_start(), 0) * 3 // 4
        return max(max(self.end - self.start, 0) * 3 // 4 - self.used, 0)

    def header(self, n: int, more: bool = False) -> bytes:
        total = self.used + n
        decoded = self._decode(self.start, total)
        out = decoded[self.used:total]
        if len(out) < n:
            self.checker.fail(f"array {self.name!r}'s header is cut short")
        self.used = total
        return out

    def read(self, n: int) -> bytes:
        if self.compressed:
            return self._decode(self._data_start(), n)[:n]
        # the length word and the data are one block: decode both, drop the word
        return self._decode(self.start, self.used + n)[self.used:self.used + n]


_CHUNK = 1 << 26  # bytes of ascii data counted at a time


def _count_tokens(data, start: int, stop: int) -> int:
    """Whitespace-separated tokens in ``data[start:stop]``, counted in chunks (memory stays
    bounded whatever the file's size)."""
    import numpy as np

    count, previous_space = 0, True
    for lo in range(start, stop, _CHUNK):
        chunk = np.frombuffer(data[lo:min(lo + _CHUNK, stop)], dtype=np.uint8)
        space = (chunk == 32) | ((chunk >= 9) & (chunk <= 13))
        starts = ~space
        starts[1:] &= space[:-1]
        starts[0] &= previous_space
        count += int(np.count_nonzero(starts))
        previous_space = bool(space[-1])
    return count


def _last_token(data, start: int, stop: int) -> bytes:
    """The last whitespace-separated token of ``data[start:stop]``."""
    end = stop
    while end > start and data[end - 1:end].isspace():
        end -= 1
    begin = end
    while begin > start and not data[begin - 1:begin].isspace() and end - begin < 64:
        begin -= 1
    return bytes(data[begin:end])


def _decompress(checker: _Checker, compressor: str, data: bytes, expected: int, name: str) -> bytes:
    try:
        if compressor == "vtkZLibDataCompressor":
            return zlib.decompressobj().decompress(data, expected)
        if compressor == "vtkLZMADataCompressor":
            return lzma.LZMADecompressor().decompress(data, expected)
        return _lz4_block(data, expected)
    except (zlib.error, lzma.LZMAError, ValueError, IndexError) as exc:
        checker.fail(f"array {name!r}'s last compressed block is damaged ({exc})")


def _lz4_count(data: bytes, i: int, count: int) -> tuple[int, int]:
    """A literal or match length of an LZ4 sequence: the token's 4-bit ``count``, and when it
    is 15, the bytes from ``data[i]`` added while they are 255; returns it and the next index."""
    if count == 15:
        while True:
            extra = data[i]
            i += 1
            count += extra
            if extra != 255:
                break
    return count, i


def _lz4_block(data: bytes, limit: int) -> bytes:
    """Decode one LZ4 block (the block format, no frame), at most ``limit`` bytes out."""
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        token = data[i]
        i += 1
        length, i = _lz4_count(data, i, token >> 4)
        out += data[i:i + length]
        i += length
        if len(out) > limit:
            raise ValueError("block larger than declared")
        if i >= n:
            break
        offset = data[i] | (data[i + 1] << 8)
        i += 2
        if offset == 0 or offset > len(out):
            raise ValueError("bad match offset")
        match, i = _lz4_count(data, i, token & 15)
        match += 4
        if len(out) + match > limit:
            raise ValueError("block larger than declared")
        for _ in range(match):  # overlapping copies repeat the bytes just written
            out.append(out[-offset])
    return bytes(out)


def check_vtk_xml(path: str | Path, *, budget: int | None = None) -> None:
    """Refuse a VTK XML file whose declared sizes its data cannot back, before VTK reads it.

    Parameters
    ----------
    path : str or Path
        A ``.vtp``, ``.vtu``, ``.vti``, ``.vts`` or ``.vtr`` file.
    budget : int, optional
        Most bytes reading it may allocate; default :func:`filters.memory.memory_limit`.

    Raises
    ------
    UnsafeFileError
        Naming the file and the first size that does not hold, in one line.
    OSError
        If the file cannot be opened.
    """
    path = Path(path)
    budget = memory_limit() if budget is None else int(budget)
    with open(path, "rb") as f:
        size = f.seek(0, 2)
        if size == 0:
            raise UnsafeFileError(f"{path} is empty")
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            _Checker(path, data, budget).run()
