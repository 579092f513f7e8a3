"""The example script runs headless and writes its figure."""

import subprocess
import sys

from conftest import REPO_ROOT


def test_frames_to_map(tmp_path):
    out = tmp_path / "map.png"
    r = subprocess.run([sys.executable, str(REPO_ROOT / "python" / "examples" / "frames_to_map.py"),
                        "-o", str(out)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 10_000 and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # steel, glass and plastic plates are classified correctly almost everywhere
    for name in ("steel", "glass", "plastic"):
        line = next(ln for ln in r.stdout.splitlines() if f"({name})" in ln)
        assert int(line.split(":")[1].split("%")[0]) >= 90, line
