"""Every scene's outputs stay bitwise identical to the recorded reference.

The runs and the digests are those of ``benchmarks/check_outputs_identical.py``; the reference,
``tests/data/outputs_reference.json``, holds the digests and the machine and library versions
they were recorded with.  Floating-point code generation depends on those, so on another
machine or with other versions the test skips (saying why) instead of failing.  A change that
means to alter a scene's numbers records a new reference:
``python benchmarks/check_outputs_identical.py --record tests/data/outputs_reference.json``.
"""

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "tests" / "data" / "outputs_reference.json"


def _checker():
    spec = importlib.util.spec_from_file_location(
        "check_outputs_identical", ROOT / "benchmarks" / "check_outputs_identical.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_scene_output_is_bitwise_identical_to_the_reference(tmp_path):
    checker = _checker()
    saved = json.loads(REFERENCE.read_text())
    if saved["fingerprint"] != checker.fingerprint():
        pytest.skip(f"reference recorded with {saved['fingerprint']}, this machine is "
                    f"{checker.fingerprint()}")
    current = checker.run_all(tmp_path)
    assert set(current) == set(saved["runs"])
    assert checker.compare(saved["runs"], current) == []
