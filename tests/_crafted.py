"""Crafted VTK XML files for the file-check tests: a real frame re-encoded (ascii, inline
binary, appended raw or base64; zlib, LZ4, LZMA or none; UInt32 or UInt64 headers), and the
same with one declared size made absurd, as an attacker would."""

import base64
import re
import struct
from pathlib import Path

from vtkmodules.vtkIOXML import (
    vtkXMLImageDataWriter,
    vtkXMLPolyDataWriter,
    vtkXMLUnstructuredGridWriter,
)

from pipeline.io.series import read_frame

_WRITERS = {".vtp": vtkXMLPolyDataWriter, ".vtu": vtkXMLUnstructuredGridWriter,
            ".vti": vtkXMLImageDataWriter}
ENCODINGS = ("ascii", "binary", "raw", "base64")
COMPRESSORS = ("none", "zlib", "lz4", "lzma")
#: What a crafted header claims: 2^50 bytes (1 PiB).
HUGE = 2**50


def reencode(source, target, encoding: str, compressor: str = "zlib", header: int = 64,
             block_size: int | None = None) -> Path:
    """Write the frame ``source`` again as ``target`` in another encoding (VTK's writer)."""
    data = read_frame(source)
    target = Path(target)
    writer = _WRITERS[target.suffix]()
    writer.SetInputData(data)
    writer.SetFileName(str(target))
    writer.SetHeaderTypeToUInt32() if header == 32 else writer.SetHeaderTypeToUInt64()
    if encoding == "ascii":
        writer.SetDataModeToAscii()
    elif encoding == "binary":
        writer.SetDataModeToBinary()
    else:
        writer.SetDataModeToAppended()
        writer.SetEncodeAppendedData(encoding == "base64")
    {"none": writer.SetCompressorTypeToNone, "zlib": writer.SetCompressorTypeToZLib,
     "lz4": writer.SetCompressorTypeToLZ4, "lzma": writer.SetCompressorTypeToLZMA}[compressor]()
    if block_size is not None:
        writer.SetBlockSize(block_size)
    assert writer.Write() == 1
    return target


def huge_points(path) -> Path:
    """``NumberOfPoints`` of the (first) piece declared 10^13."""
    path = Path(path)
    data = path.read_bytes()
    data, n = re.subn(rb'NumberOfPoints="\d+"', b'NumberOfPoints="10000000000000"', data,
                      count=1)
    assert n == 1
    path.write_bytes(data)
    return path


def huge_last_offset(path) -> Path:
    """The last cell offset of an ascii file's last non-empty offsets array set to 10^14."""
    path = Path(path)
    data = path.read_bytes()
    found = list(re.finditer(rb'Name="offsets"[^>]*>\s*([\d\s]*\d)\s*<', data))
    assert found, "no ascii offsets"
    match = found[-1]
    values = match.group(1).split()
    values[-1] = b"100000000000000"
    path.write_bytes(data[:match.start(1)] + b" ".join(values) + data[match.end(1):])
    return path


def _word(data: bytes) -> str:
    return "<Q" if b'header_type="UInt64"' in data else "<I"


def huge_block_header(path, word: int = 2) -> Path:
    """The first array's compressed block header claims ``HUGE`` bytes in word ``word`` (0
    the block count, 1 the block size, 2 the last block's size), or, uncompressed, its length
    word does; in whatever encoding the file has."""
    path = Path(path)
    data = path.read_bytes()
    fmt = _word(data)
    size = struct.calcsize(fmt)
    compressed = b"compressor=" in data
    index = word if compressed else 0
    value = HUGE if size == 8 else 2**32 - 1
    raw = re.search(rb'<AppendedData encoding="raw">\s*_', data)
    if raw is not None:
        pos = raw.end() + index * size
        path.write_bytes(data[:pos] + struct.pack(fmt, value) + data[pos + size:])
        return path
    match = re.search(rb'(?:format="binary"[^>]*>\s*|<AppendedData encoding="base64">\s*_)', data)
    assert match is not None, "no binary data"
    start = match.end()
    chars = 4 * (3 * size) // 3  # three header words: a whole number of base64 groups
    words = bytearray(base64.b64decode(data[start:start + chars]))
    struct.pack_into(fmt, words, index * size, value)
    path.write_bytes(data[:start] + base64.b64encode(bytes(words)) + data[start + chars:])
    return path
