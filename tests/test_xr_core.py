"""The immersive page's pure logic (viewer/xr_core.js) in node's test runner: pinch validation in
either finger order, the 1 s hold, thresholds from the URL, the calibration's rigid fit and the CSV.

Needs node (Debian's ``nodejs``; .ci/run installs it). Outside CI it is skipped when node is
missing.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

NODE = shutil.which("node")
TESTS = Path(__file__).parent / "js"


def test_the_pure_logic_in_nodes_test_runner():
    if NODE is None:
        if os.environ.get("CI"):
            pytest.fail("node missing; .ci/run installs Debian's nodejs")
        pytest.skip("node is not installed (apt-get install nodejs)")
    proc = subprocess.run([NODE, "--test", *sorted(str(p) for p in TESTS.glob("*.test.mjs"))],
                          capture_output=True, text=True, timeout=120, check=False)
    summary = [line for line in proc.stdout.splitlines()
               if line.startswith(("# pass", "# fail", "not ok"))]
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "# fail 0" in summary and any(line.startswith("# pass") and int(line.split()[-1]) >= 8
                                         for line in summary), summary
