"""Check that every scene writes bitwise identical outputs: record a reference, compare against it.

Runs every scene (and its variants: solvers, integrators, isotropic and anisotropic surfaces)
through the command line at small, fast parameters, plus ``blobflow surface`` runs over a written
particle series, and records a SHA-256 digest of every file written (but the provenance records
``NAME.source.json`` of ``surface`` runs, which hold the machine's paths and times):

* ``raw``: the file's bytes;
* ``decoded`` (VTK XML frames): points, cells and every point, cell and field array (name,
  dtype, shape, values), read back with VTK's own readers, so that a difference in the data is
  told apart from one in the file's layout; for the run records (``scene.json``), the record
  with parameter values renamed on purpose (:data:`RENAMED_VALUES`) in their new names.

Usage::

    python benchmarks/check_outputs_identical.py --record REFERENCE.json   # before a change
    python benchmarks/check_outputs_identical.py --compare REFERENCE.json  # after it

``--compare`` prints one line per file that differs and exits with 1 if any does (0 when all
are identical).  ``--only NAME`` restricts either mode to some of the runs (repeatable).  The
digests depend on the machine and on the versions of NumPy, Numba and VTK (floating-point code
generation); the reference records them, and a comparison across different ones says so.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

#: (name, blobflow command line arguments); ``{out}`` is the run's folder, ``{root}`` the root
#: of all runs (so that ``surface`` runs can read a particle series written before them).
RUNS = [
    ("bouncing", ["run", "bouncing", "--frames", "3", "--set", "count=4"]),
    ("cloth_drape", ["run", "cloth_drape", "--frames", "3", "--set", "resolution=8"]),
    ("cloth_drape_pcg", ["run", "cloth_drape", "--frames", "3", "--set", "resolution=8",
                         "--set", "solver=pcg"]),
    ("cloth_drape_direct", ["run", "cloth_drape", "--frames", "3", "--set", "resolution=8",
                            "--set", "solver=direct"]),
    ("hair", ["run", "hair", "--frames", "3", "--set", "strands=12", "--set", "segments=5"]),
    ("jello_drop", ["run", "jello_drop", "--frames", "3", "--set", "spacing=0.06"]),
    ("jello_fem", ["run", "jello_fem", "--frames", "3", "--set", "spacing=0.06"]),
    ("jello_fem_corotated", ["run", "jello_fem", "--frames", "3", "--set", "spacing=0.06",
                             "--set", "material=corotated"]),
    ("noise_smoke", ["run", "noise_smoke", "--frames", "4", "--set", "rate=3000",
                     "--set", "max_particles=300", "--set", "surface=true"]),
    ("noise_smoke_euler", ["run", "noise_smoke", "--frames", "3", "--set", "rate=3000",
                           "--set", "max_particles=300", "--set", "integrator=euler",
                           "--set", "surface=false"]),
    ("noise_smoke_rk2", ["run", "noise_smoke", "--frames", "3", "--set", "rate=3000",
                         "--set", "max_particles=300", "--set", "integrator=rk2",
                         "--set", "surface=false"]),
    ("noise_smoke_backward", ["run", "noise_smoke", "--frames", "3", "--set", "rate=3000",
                              "--set", "max_particles=300",
                              "--set", "integrator=linearized_backward_euler",
                              "--set", "surface=false"]),
    ("dam_break", ["run", "dam_break", "--frames", "4", "--set", "spacing=0.02"]),
    ("dam_break_wcsph_isotropic", ["run", "dam_break", "--frames", "3", "--set", "spacing=0.02",
                                   "--set", "solver=wcsph", "--set", "anisotropic=false"]),
    ("drop", ["run", "drop", "--frames", "3", "--set", "spacing=0.02"]),
    ("floating", ["run", "floating", "--frames", "3", "--set", "spacing=0.025",
                  "--set", "box_height=0.05"]),
    ("jello_splash", ["run", "jello_splash", "--frames", "3", "--set", "spacing=0.025"]),
    # `blobflow surface` over a copy of a particle series without its scene.json, with every
    # option given, so that only the code (not a default) decides the result
    ("particles_copy", ["copy-series", "{root}/dam_break/particles.pvd"]),
    ("drop_particles_copy", ["copy-series", "{root}/drop/particles.pvd"]),
    ("surface", ["surface", "{root}/particles_copy/particles.pvd", "--radius", "0.01",
                 "--kernel", "sph", "--smooth-iterations", "20", "--option", "pass_band=0.001",
                 "--option", "feature_smoothing=0", "--option", "anisotropic=false",
                 "--option", "volume_correction=false"]),
    ("surface_dense_blobby", ["surface", "{root}/particles_copy/particles.pvd",
                              "--radius", "0.01", "--kernel", "blobby", "--option", "sparse=false",
                              "--smooth-iterations", "0", "--option", "feature_smoothing=0",
                              "--option", "anisotropic=false",
                              "--option", "volume_correction=false"]),
    ("surface_anisotropic", ["surface", "{root}/drop_particles_copy/particles.pvd",
                             "--radius", "0.01", "--kernel", "sph", "--smooth-iterations", "20",
                             "--option", "pass_band=0.001", "--option", "anisotropic=true",
                             "--option", "feature_smoothing=5",
                             "--option", "volume_correction=true"]),
    ("smoke_particles_copy", ["copy-series", "{root}/noise_smoke/particles.pvd"]),
    ("surface_tetrahedra", ["surface", "{root}/particles_copy/particles.pvd", "--radius", "0.01",
                            "--kernel", "sph", "--smooth-iterations", "0", "--option",
                            "feature_smoothing=0", "--option", "anisotropic=false",
                            "--option", "contour=tetrahedra",
                            "--option", "volume_correction=true"]),
    ("surface_zhu_bridson", ["surface", "{root}/particles_copy/particles.pvd", "--radius", "0.01",
                             "--kernel", "zhu_bridson", "--smooth-iterations", "0",
                             "--option", "feature_smoothing=0", "--option", "anisotropic=false",
                             "--option", "volume_correction=false"]),
    ("surface_metaball_anisotropic", ["surface", "{root}/particles_copy/particles.pvd",
                                      "--radius", "0.01", "--kernel", "metaball",
                                      "--smooth-iterations", "0", "--option", "feature_smoothing=0",
                                      "--option", "anisotropic=true",
                                      "--option", "volume_correction=false"]),
    ("surface_dense_anisotropic", ["surface", "{root}/drop_particles_copy/particles.pvd",
                                   "--radius", "0.01", "--kernel", "sph", "--option",
                                   "sparse=false", "--smooth-iterations", "0", "--option",
                                   "feature_smoothing=3",
                                   "--option", "anisotropic=true",
                                   "--option", "volume_correction=true"]),
    ("surface_radii_anisotropic", ["surface", "{root}/smoke_particles_copy/particles.pvd",
                                   "--radius", "0.02", "--kernel", "sph", "--option",
                                   "radius_array=size", "--smooth-iterations", "0",
                                   "--option", "feature_smoothing=0", "--option",
                                   "anisotropic=true", "--option", "volume_correction=false"]),
    ("surface_radii_blobby", ["surface", "{root}/smoke_particles_copy/particles.pvd",
                              "--radius", "0.02", "--kernel", "blobby", "--option",
                              "radius_array=size", "--smooth-iterations", "0",
                              "--option", "feature_smoothing=0", "--option", "anisotropic=false",
                              "--option", "volume_correction=false"]),
]


#: Scene parameter values renamed on purpose: ``(parameter, old value) -> new value``. A run
#: record (``scene.json``) that differs from the reference by these alone counts as identical.
RENAMED_VALUES = {("integrator", "backward_euler"): "linearized_backward_euler"}


def _sha(*chunks) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c if isinstance(c, bytes) else str(c).encode())
    return h.hexdigest()


def _array_digest(name, vtk_array) -> list:
    import numpy as np
    from vtkmodules.util import numpy_support

    values = np.ascontiguousarray(numpy_support.vtk_to_numpy(vtk_array))
    return [name, str(values.dtype), list(values.shape), _sha(values.tobytes())]


def _attributes(data) -> list:
    out = []
    for i in range(data.GetNumberOfArrays()):
        arr = data.GetAbstractArray(i)
        if arr is None or not arr.IsNumeric():
            out.append([data.GetArrayName(i), "non-numeric"])
            continue
        out.append(_array_digest(arr.GetName(), arr))
    return sorted(out, key=lambda a: a[0] or "")


def decoded_digest(path: Path) -> dict:
    """Digest of a VTK XML frame's data: points, cells, point, cell and field arrays."""
    from vtkmodules.vtkIOXML import (
        vtkXMLImageDataReader,
        vtkXMLPolyDataReader,
        vtkXMLUnstructuredGridReader,
    )

    reader = {".vtp": vtkXMLPolyDataReader, ".vtu": vtkXMLUnstructuredGridReader,
              ".vti": vtkXMLImageDataReader}[path.suffix]()
    reader.SetFileName(str(path))
    reader.Update()
    data = reader.GetOutput()
    record = {"class": data.GetClassName(), "n_points": data.GetNumberOfPoints(),
              "n_cells": data.GetNumberOfCells()}
    if hasattr(data, "GetPoints") and data.GetPoints() is not None:
        record["points"] = _array_digest("points", data.GetPoints().GetData())
    if path.suffix == ".vtp":
        for kind in ("Verts", "Lines", "Polys", "Strips"):
            cells = getattr(data, f"Get{kind}")()
            record[kind.lower()] = [_array_digest("offsets", cells.GetOffsetsArray()),
                                    _array_digest("connectivity", cells.GetConnectivityArray())]
    elif path.suffix == ".vtu":
        cells = data.GetCells()
        record["cells"] = [_array_digest("offsets", cells.GetOffsetsArray()),
                           _array_digest("connectivity", cells.GetConnectivityArray()),
                           _array_digest("types", data.GetCellTypes())]  # VTK >= 9.4
    record["point_data"] = _attributes(data.GetPointData())
    record["cell_data"] = _attributes(data.GetCellData())
    record["field_data"] = _attributes(data.GetFieldData())
    return record


def _renamed(record: dict) -> dict:
    """A run record with the parameter values of :data:`RENAMED_VALUES` in their new names."""
    params = dict(record.get("parameters", {}))
    for (name, old), new in RENAMED_VALUES.items():
        if params.get(name) == old:
            params[name] = new
    return {**record, "parameters": params}


def digest_folder(folder: Path) -> dict:
    """``{relative path: {"raw": sha, "decoded": sha or None}}`` of every file below ``folder``."""
    files = {}
    # NAME.source.json records where a `surface` run's input is and when its frames were
    # written (absolute paths, modification times): provenance for --resume, not an output
    for path in sorted(p for p in folder.rglob("*") if p.is_file()
                       and not p.name.endswith(".source.json")):
        rel = path.relative_to(folder).as_posix()
        entry = {"raw": _sha(path.read_bytes()), "decoded": None}
        if path.suffix in (".vtp", ".vtu", ".vti"):
            entry["decoded"] = _sha(json.dumps(decoded_digest(path), sort_keys=True))
        elif path.name == "scene.json":
            entry["decoded"] = _sha(json.dumps(_renamed(json.loads(path.read_text())),
                                               sort_keys=True))
        files[rel] = entry
    return files


def fingerprint() -> dict:
    """What the digests depend on besides the code: the machine and the numeric libraries."""
    import llvmlite
    import numba
    import numpy
    import vtkmodules

    cpu, flags = "", ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name") and not cpu:
                cpu = line.split(":", 1)[1].strip()
            if line.startswith("flags") and not flags:
                flags = " ".join(sorted(line.split(":", 1)[1].split()))
    except OSError:
        pass
    return {"machine": platform.machine(), "cpu": cpu, "cpu_flags": _sha(flags)[:16],
            "python": platform.python_version(),
            "numpy": numpy.__version__, "numba": numba.__version__,
            "llvmlite": llvmlite.__version__,
            "vtk": getattr(vtkmodules, "__version__", "")}


def _copy_series(collection: Path, folder: Path) -> None:
    """Copy a written series (collection, ``.series`` file, frames folder) into ``folder``."""
    import shutil

    stem = collection.name.split(".")[0]
    folder.mkdir(parents=True, exist_ok=True)
    for path in collection.parent.glob(f"{stem}.*"):
        shutil.copy2(path, folder / path.name)
    shutil.copytree(collection.parent / stem, folder / stem)


def _legacy(argv: list) -> list:
    """``argv`` with the values of :data:`RENAMED_VALUES` in their former names (for a reference
    recorded on the code before the renames)."""
    out = list(argv)
    for i in range(len(out) - 1):
        if out[i] == "--set":
            name, _, value = out[i + 1].partition("=")
            for (param, old), new in RENAMED_VALUES.items():
                if name == param and value == new:
                    out[i + 1] = f"{name}={old}"
    return out


def run_all(root: Path, only=None, quiet: bool = True, legacy: bool = False) -> dict:
    """Run the selected :data:`RUNS` into ``root/NAME`` and digest what each wrote (``legacy``:
    with the parameter values the code before :data:`RENAMED_VALUES` knew)."""
    from pipeline.cli import main

    results = {}
    selected = [r for r in RUNS if not only or r[0] in only]
    for name, argv in selected:
        out = root / name
        argv = [a.format(root=root, out=out) for a in argv]
        if legacy:
            argv = _legacy(argv)
        if argv[0] == "copy-series":
            _copy_series(Path(argv[1]), out)
            continue
        argv += ["--out", str(out), "--quiet"] + (["--no-render"] if argv[0] == "run" else [])
        start = time.perf_counter()
        code = main(argv)
        if not quiet:
            print(f"{name}: exit {code} in {time.perf_counter() - start:.1f} s", flush=True)
        if code != 0:
            raise RuntimeError(f"run {name!r} ({' '.join(argv)}) exited with {code}")
        results[name] = digest_folder(out)
    return results


def compare(reference: dict, current: dict) -> list[str]:
    """Lines describing every difference between two ``{run: {file: entry}}`` records."""
    lines = []
    for run in sorted(set(reference) | set(current)):
        ref, cur = reference.get(run), current.get(run)
        if ref is None or cur is None:
            lines.append(f"{run}: only in the {'current run' if ref is None else 'reference'}")
            continue
        for rel in sorted(set(ref) | set(cur)):
            a, b = ref.get(rel), cur.get(rel)
            if a is None or b is None:
                where = "current run" if a is None else "reference"
                lines.append(f"{run}/{rel}: only in the {where}")
            elif a["decoded"] != b["decoded"]:
                lines.append(f"{run}/{rel}: data differ")
            elif a["raw"] != b["raw"] and a["decoded"] is None:
                lines.append(f"{run}/{rel}: file bytes differ")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--record", metavar="JSON", help="write the digests to JSON")
    mode.add_argument("--compare", metavar="JSON", help="compare against the digests in JSON")
    parser.add_argument("--only", action="append", metavar="NAME",
                        help=f"run only these ({', '.join(n for n, _ in RUNS)})")
    parser.add_argument("--keep", metavar="DIR", help="write the runs here and keep them")
    parser.add_argument("--legacy", action="store_true",
                        help="pass renamed parameter values by their former names (to record a "
                             "reference on the code before the renames)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="blobflow-identity-") as tmp:
        root = Path(args.keep) if args.keep else Path(tmp)
        current = run_all(root, args.only, quiet=False, legacy=args.legacy)
    count = sum(len(files) for files in current.values())
    if args.record:
        Path(args.record).write_text(json.dumps(
            {"fingerprint": fingerprint(), "runs": current}, indent=1, sort_keys=True) + "\n")
        print(f"recorded {count} files of {len(current)} runs in {args.record} "
              f"({time.perf_counter() - start:.0f} s)")
        return 0
    saved = json.loads(Path(args.compare).read_text())
    reference = saved["runs"]
    if args.only:
        reference = {k: v for k, v in reference.items() if k in args.only}
    if saved.get("fingerprint") != fingerprint():
        print(f"note: the reference was recorded with {saved.get('fingerprint')}, this is "
              f"{fingerprint()}: digests may differ for that reason alone")
    lines = compare(reference, current)
    for line in lines:
        print(line)
    print(f"{'IDENTICAL' if not lines else 'DIFFERENT'}: {count} files of {len(current)} runs "
          f"compared, {len(lines)} difference(s) ({time.perf_counter() - start:.0f} s)")
    return 1 if lines else 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    sys.exit(main())
