"""Issue 31, item 4: a crafted VTK XML file never aborts the process.

VTK's readers allocate what a file declares; ``std::bad_alloc`` then aborts the process (exit
134) where no Python code can catch it. :mod:`pipeline.io.xmlcheck` checks every declared size in
every encoding before VTK reads. Each reader path of the command line gets a crafted file in a
process of its own (an abort must not take pytest with it) and answers exit 2 with one line;
a property test feeds the reader seeded mutations of real frames (truncated, a size or header
multiplied, an encoding swapped without re-encoding) and accepts only a clear error or the
frame read back exactly.
"""

import json
import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from _crafted import (
    COMPRESSORS,
    ENCODINGS,
    huge_block_header,
    huge_last_offset,
    huge_points,
    reencode,
)

from pipeline.cli import main
from pipeline.io.series import read_frame, write_frame
from pipeline.io.xmlcheck import UnsafeFileError, check_vtk_xml

ROOT = Path(__file__).resolve().parents[2]
WORKER = ROOT / "tests" / "_read_worker.py"


def _env():
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), str(ROOT / "tests"), os.environ.get("PYTHONPATH", "")])}


def _blobflow(*argv, cwd=None, module="pipeline", timeout=240):
    result = subprocess.run([sys.executable, "-m", module, *map(str, argv)], capture_output=True,
                            text=True, timeout=timeout, env=_env(), cwd=cwd)
    lines = [line for line in result.stderr.splitlines() if line.strip()
             and not line.startswith("blobflow: compiling")]
    return result.returncode, lines


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A small run of the bouncing scene (4 frames of 8 particles)."""
    out = tmp_path_factory.mktemp("fc") / "run"
    assert main(["run", "bouncing", "--duration", "0.1", "--out", str(out), "--no-render",
                 "--quiet", "--set", "count=2"]) == 0
    return out


def _frame(seed=0, n=120):
    rng = np.random.default_rng(seed)
    cloud = pv.PolyData(rng.random((n, 3)))
    cloud["velocity"] = rng.random((n, 3))
    cloud["id"] = np.arange(n)
    return cloud


# -- the checker on each crafted kind, in this process (VTK never sees the files) ------------
@pytest.mark.parametrize("encoding", ENCODINGS)
def test_huge_point_count_is_refused_in_every_encoding(tmp_path, encoding):
    source = write_frame(_frame(), tmp_path / "f.vtp")
    crafted = huge_points(reencode(source, tmp_path / f"{encoding}.vtp", encoding))
    with pytest.raises(UnsafeFileError, match=r"declares 10000000000000 tuples.*more than its "
                                              r"data holds") as info:
        check_vtk_xml(crafted)
    assert str(crafted) in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("encoding", ["binary", "raw", "base64"])
@pytest.mark.parametrize("compressor", COMPRESSORS)
@pytest.mark.parametrize("header", [32, 64])
def test_block_headers_claiming_a_pebibyte_are_refused(tmp_path, encoding, compressor, header):
    source = write_frame(_frame(), tmp_path / "f.vtp")
    name = f"{encoding}-{compressor}-{header}.vtp"
    good = reencode(source, tmp_path / name, encoding, compressor, header)
    check_vtk_xml(good)  # the honest file passes
    for word in ((0, 1, 2) if compressor != "none" else (0,)):
        crafted = shutil.copy(good, tmp_path / f"w{word}-{name}")
        huge_block_header(crafted, word)
        if compressor != "none" and word == 1:  # one block: its size is the last one's
            check_vtk_xml(crafted)
            continue
        with pytest.raises(UnsafeFileError, match=r"claims|claiming|blocks|runs past"):
            check_vtk_xml(crafted)


def test_last_cell_offset_beyond_the_connectivity_is_refused(tmp_path):
    source = write_frame(pv.Sphere(theta_resolution=8, phi_resolution=8), tmp_path / "s.vtp")
    crafted = huge_last_offset(reencode(source, tmp_path / "a.vtp", "ascii"))
    with pytest.raises(UnsafeFileError, match="offsets end at 100000000000000"):
        check_vtk_xml(crafted)


def test_memory_budget_and_what_the_checker_does_not_understand(tmp_path):
    source = write_frame(_frame(n=4000), tmp_path / "f.vtp")
    check_vtk_xml(source)
    with pytest.raises(UnsafeFileError, match=r"memory budget of 1 KiB"):
        check_vtk_xml(source, budget=1024)
    text = source.read_bytes()
    for label, change in (("comment", text.replace(b"<PolyData>", b"<PolyData><!-- x -->", 1)),
                          ("entity", text.replace(b'Name="id"', b'Name="&x;"', 1)),
                          ("collection", text.replace(b'type="PolyData"',
                                                      b'type="Collection"', 1)),
                          ("empty", b"")):
        path = tmp_path / f"{label}.vtp"
        path.write_bytes(change)
        with pytest.raises(UnsafeFileError):
            check_vtk_xml(path)


def test_multi_block_lz4_and_lzma_offsets_are_decoded(tmp_path):
    """A surface of several compressed blocks per array: the last offset read from its last
    block (LZ4 decoded by the checker's own block decoder) equals VTK's."""
    sphere = pv.Sphere(theta_resolution=60, phi_resolution=60)
    source = write_frame(sphere, tmp_path / "s.vtp")
    for compressor in ("zlib", "lz4", "lzma"):
        for encoding in ("binary", "raw", "base64"):
            path = reencode(source, tmp_path / f"{compressor}-{encoding}.vtp", encoding,
                            compressor, block_size=1024)
            check_vtk_xml(path)
            back = pv.wrap(read_frame(path))
            assert back.n_cells == sphere.n_cells
            np.testing.assert_array_equal(back.faces, sphere.faces)


# -- every reader path of the command line, each in its own process --------------------------
def _crafted_series(run: Path, folder: Path, craft) -> Path:
    """A copy of ``run`` whose last frame (the checkpoint a resume reads) is crafted."""
    copy = folder / "crafted"
    shutil.copytree(run, copy)
    frame = copy / "particles" / "particles_000003.vtp"
    craft(frame)
    return copy


def _ascii_points(frame):
    tmp = frame.with_name("x.vtp")
    huge_points(reencode(frame, tmp, "ascii"))
    os.replace(tmp, frame)


def _inline(compressor, word=2):
    def craft(frame):
        tmp = frame.with_name("x.vtp")
        huge_block_header(reencode(frame, tmp, "binary", compressor), word)
        os.replace(tmp, frame)
    return craft


def _base64(frame):
    tmp = frame.with_name("x.vtp")
    huge_block_header(reencode(frame, tmp, "base64", "zlib"), 2)
    os.replace(tmp, frame)


def _raw(frame):
    huge_block_header(frame, 2)


@pytest.mark.timeout(600)
def test_every_reader_path_answers_a_crafted_frame_with_one_line(run, tmp_path):
    crafts = {"ascii": _ascii_points, "inline": _inline("zlib"), "base64": _base64,
              "raw": _raw, "lzma": _inline("lzma", 0)}
    series = {k: _crafted_series(run, tmp_path / k, c) for k, c in crafts.items()}
    bad = {k: s / "particles" / "particles_000003.vtp" for k, s in series.items()}
    pvd = {k: s / "particles.pvd" for k, s in series.items()}
    outputs = tmp_path / "outputs"
    checks = [
        (("info", pvd["ascii"]), "ascii"),
        (("render", pvd["inline"], "--turntable", "2", "--size", "64x48", "--out",
          outputs / "r.gif", "-q"), "inline"),
        (("surface", pvd["base64"], "--out", outputs / "s", "-q"), "base64"),
        (("run", "bouncing", "--duration", "0.2", "--out", series["raw"], "--no-render", "-q",
          "--resume"), "raw"),
        (("run", "jello_drop", "--set", f"mesh={bad['lzma']}", "--frames", "2", "--out",
          outputs / "j", "--no-render", "-q"), "lzma"),
    ]
    try:
        import pxr  # noqa: F401

        checks.append((("export", pvd["ascii"], "--usd", outputs / "x.usda"), "ascii"))
    except ImportError:
        pass
    for argv, kind in checks:
        code, lines = _blobflow(*argv)
        assert code == 2, (argv, lines)
        assert len(lines) == 1 and lines[0].startswith("blobflow: error: "), (argv, lines)
        assert str(bad[kind]) in lines[0], (argv, lines)
    # the run resumed over a crafted checkpoint frame changed nothing
    assert not outputs.exists() or not any(outputs.rglob("*.*"))
    # the bridge worker: the one-shot command and the serving loop
    code, lines = _blobflow("surface", bad["inline"], tmp_path / "b.vtp", '{"radius": 0.01}',
                            module="pipeline.paraview.bridge")
    assert code == 2 and len(lines) == 1 and str(bad["inline"]) in lines[0], lines
    requests = "".join(json.dumps({"command": "surface", "source": str(bad[k]),
                                   "target": str(tmp_path / f"{k}.vtp"),
                                   "options": {"radius": 0.01}}) + "\n" for k in bad)
    answer = subprocess.run([sys.executable, "-m", "pipeline.paraview.bridge", "serve"],
                            input=requests,
                            capture_output=True, text=True, timeout=240, env=_env())
    assert answer.returncode == 0, answer.stderr[-2000:]
    replies = [json.loads(line) for line in answer.stdout.splitlines()]
    assert [r["ok"] for r in replies] == [False] * len(bad)
    assert all(str(bad[k]) in r["error"] for k, r in zip(bad, replies, strict=False))
    assert not list(tmp_path.glob("*.vtp"))


# -- property test: mutated copies of real frames ----------------------------------------------
def _header_words(data: bytes) -> list[int]:
    """Byte positions of the raw appended arrays' header words (not their data)."""
    marker = re.search(rb'<AppendedData encoding="raw">\s*_', data)
    if marker is None:
        return []
    size = 8 if b'header_type="UInt64"' in data[:1000] else 4
    fmt = "<Q" if size == 8 else "<I"
    compressed = b"compressor=" in data[:1000]
    positions = []
    for match in re.finditer(rb'offset="(\d+)"', data[:marker.start()]):
        start = marker.end() + int(match.group(1))
        if start + size > len(data):
            continue
        count = struct.unpack(fmt, data[start:start + size])[0] if compressed else 0
        words = 3 + min(count, 64) if compressed else 1
        positions += [start + k * size for k in range(words) if start + (k + 1) * size <= len(data)]
    return positions


_SWAPS = [(b'encoding="raw"', b'encoding="base64"'), (b'encoding="base64"', b'encoding="raw"'),
          (b'format="appended"', b'format="binary"'), (b'format="binary"', b'format="ascii"'),
          (b'format="ascii"', b'format="binary"'), (b'header_type="UInt64"',
                                                    b'header_type="UInt32"'),
          (b'header_type="UInt32"', b'header_type="UInt64"'),
          (b' compressor="vtkZLibDataCompressor"', b""),
          (b"vtkZLibDataCompressor", b"vtkLZ4DataCompressor"),
          (b"vtkLZ4DataCompressor", b"vtkLZMADataCompressor"),
          (b"LittleEndian", b"BigEndian"), (b'type="Int64"', b'type="Int32"')]


def _mutate(data: bytes, rng) -> bytes | None:
    """One seeded mutation that changes a size or an encoding, never a value: truncation, a
    declared count or a header word multiplied, an encoding attribute swapped."""
    kind = int(rng.integers(4))
    if kind == 0:
        return data[:int(rng.integers(len(data)))]
    if kind == 1:
        counts = list(re.finditer(rb'(?:NumberOf\w+|Extent|WholeExtent)="([\d ]+)"', data))
        if not counts:
            return None
        match = counts[int(rng.integers(len(counts)))]
        values = match.group(1).split()
        k = int(rng.integers(len(values)))
        values[k] = str(int(values[k]) * int(10 ** rng.integers(1, 14)) + 1).encode()
        return data[:match.start(1)] + b" ".join(values) + data[match.end(1):]
    if kind == 2:
        words = _header_words(data)
        if not words:
            return None
        pos = words[int(rng.integers(len(words)))]
        size = 8 if b'header_type="UInt64"' in data[:1000] else 4
        fmt = "<Q" if size == 8 else "<I"
        value = struct.unpack(fmt, data[pos:pos + size])[0]
        value = min(value * 2 ** int(rng.integers(1, 40)) + 1, 2 ** (8 * size) - 1)
        return data[:pos] + struct.pack(fmt, value) + data[pos + size:]
    old, new = _SWAPS[int(rng.integers(len(_SWAPS)))]
    return data.replace(old, new) if old in data else None


@pytest.mark.timeout(600)
def test_mutated_real_frames_read_back_exactly_or_fail_with_one_line(run, tmp_path, rng):
    """Real frames (particles with a checkpoint, a closed surface, tetrahedra), each in every
    encoding and then mutated 25 times (seeded): every read, in worker processes, is the frame
    exactly or a one-line SeriesError; none aborts."""
    sources = {"particles": run / "particles" / "particles_000002.vtp",
               "surface": write_frame(pv.Sphere(theta_resolution=12, phi_resolution=12),
                                      tmp_path / "surface.vtp"),
               "tets": write_frame(pv.ImageData(dimensions=(4, 4, 4))
                                   .cast_to_unstructured_grid().triangulate(),
                                   tmp_path / "tets.vtu")}
    outcomes = {"same": 0, "error": 0}
    for label, source in sources.items():
        encoded = [source] + [
            reencode(source, tmp_path / f"{label}-{e}-{c}-{h}{source.suffix}", e, c, h)
            for e in ENCODINGS for c in COMPRESSORS for h in (32, 64)
            if not (e == "ascii" and (c != "none" or h == 32))]
        cases = []
        for k in range(25):
            base = encoded[int(rng.integers(len(encoded)))]
            mutated = _mutate(base.read_bytes(), rng)
            if mutated is not None:
                path = tmp_path / f"m{k}-{base.name}"
                path.write_bytes(mutated)
                cases.append(path)
        files = [str(p) for p in encoded + cases]
        while files:
            result = subprocess.run([sys.executable, str(WORKER), str(source), *files],
                                    capture_output=True, text=True, timeout=300, env=_env())
            lines = result.stdout.splitlines()
            for path, line in zip(files, lines, strict=False):
                verdict = line.split()[0]
                assert verdict in ("same", "error"), f"{path}: read as a different frame"
                assert verdict == "same" or not path.startswith(str(tmp_path / label)), \
                    f"the honest re-encoding {path} was refused: {line}"
                outcomes[verdict] += 1
            assert result.returncode == 0, (
                f"reading {files[len(lines)]} aborted the process (exit {result.returncode}): "
                f"{result.stderr.strip().splitlines()[-1:]}")
            files = files[len(lines):]
    assert outcomes["error"] >= 30 and outcomes["same"] >= 45
