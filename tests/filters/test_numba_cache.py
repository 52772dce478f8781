"""Numba's cache for blobflow's kernels (filters.numba_cache): a kernel is compiled again when a
helper in another file changes, and a damaged cache entry is compiled again with a warning
instead of crashing the run.  Each case runs fresh Python processes on a small package of its
own in a temporary folder, registered as one of blobflow's packages."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

RUN = textwrap.dedent("""
    import os, sys
    sys.path.insert(0, {tmp!r})
    from filters import numba_cache
    numba_cache.package_roots().append(os.path.normcase({pkg!r}) + os.sep)
    from probe.kernel import twice_helper
    print("RESULT", twice_helper(1.0))
""")


def _package(tmp_path, helper_value):
    pkg = tmp_path / "probe"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text(textwrap.dedent(f"""
        from numba import njit

        @njit(cache=True, inline="always")
        def helper(x):
            return x + {helper_value}
    """))
    kernel = pkg / "kernel.py"
    if not kernel.exists():
        kernel.write_text(textwrap.dedent("""
            from numba import njit
            from probe.helper import helper

            @njit(cache=True)
            def twice_helper(x):
                return 2.0 * helper(x)
        """))
    return pkg


def _touch_later(path, seconds):
    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + int(seconds * 1e9)))


def _run(tmp_path, pkg, env_extra=None):
    env = dict(os.environ, PYTHONPATH=str(REPO), **(env_extra or {}))
    env.pop("NUMBA_CACHE_DIR", None)  # the cache beside the sources, as for the package
    done = subprocess.run([sys.executable, "-c", RUN.format(tmp=str(tmp_path), pkg=str(pkg))],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    value = [line for line in done.stdout.splitlines() if line.startswith("RESULT")][-1]
    return float(value.split()[1]), done.stderr


def _cache_files(pkg):
    return sorted((pkg / "__pycache__").glob("*.nb[ic]"))


def test_a_kernel_is_compiled_again_when_a_helper_in_another_file_changes(tmp_path):
    pkg = _package(tmp_path, 1.0)
    assert _run(tmp_path, pkg)[0] == 4.0  # 2 (1 + 1)
    assert _cache_files(pkg), "the kernel was not cached"
    assert _run(tmp_path, pkg)[0] == 4.0  # from the cache
    _package(tmp_path, 10.0)  # only the helper's file changes
    _touch_later(pkg / "helper.py", 5)
    assert _run(tmp_path, pkg)[0] == 22.0  # 2 (1 + 10): not the cached 4


@pytest.mark.parametrize("damage", ["index", "data"])
def test_a_damaged_cache_entry_is_compiled_again_with_a_warning(tmp_path, damage):
    pkg = _package(tmp_path, 1.0)
    assert _run(tmp_path, pkg)[0] == 4.0
    files = [p for p in _cache_files(pkg) if p.suffix == (".nbi" if damage == "index" else ".nbc")]
    assert files
    for p in files:  # truncated, as a killed process or a full disk leaves a file
        data = p.read_bytes()
        p.write_bytes(data[: len(data) // 2])
    value, err = _run(tmp_path, pkg)
    assert value == 4.0
    assert "unreadable Numba cache entry" in err and str(pkg / "__pycache__") in err, err
    value, err = _run(tmp_path, pkg)  # the entry was rewritten: no warning the next time
    assert value == 4.0
    assert "unreadable" not in err, err
