"""Python raises with exactly the message the CLI prints after ``polarid: error: ``:
the error, then each cause once, joined by ``: `` (one Rust function builds both)."""

import subprocess

import pytest

import polarid


def cli_message(exe, *args, cwd):
    """The CLI's error message (without the ``polarid: error: `` prefix)."""
    out = subprocess.run([str(exe), *args], cwd=cwd, capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    prefix = "polarid: error: "
    assert out.stderr.startswith(prefix) and out.stderr.endswith("\n"), out.stderr
    return out.stderr[len(prefix) : -1]


def test_missing_file_message_matches_the_cli(tmp_path, polarid_cli):
    missing = tmp_path / "nope.toml"
    with pytest.raises(FileNotFoundError) as e:
        polarid.load_manifest(missing)
    want = cli_message(polarid_cli, "measure", str(missing), "-o", "m.csv", cwd=tmp_path)
    assert str(e.value) == want
    # The operating system's reason appears once, after the file name.
    assert want.startswith(f"{missing}: ")
    assert want.count("os error") == 1


def test_bad_manifest_field_message_matches_the_cli(tmp_path, polarid_cli):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[region]]\nname = "A"\nrect = [0, 0, 0, 4]\n')
    with pytest.raises(ValueError) as e:
        polarid.load_manifest(bad)
    want = cli_message(polarid_cli, "measure", str(bad), "-o", "m.csv", cwd=tmp_path)
    assert str(e.value) == want
    assert "line 3" in want and "region[1].rect" in want
