"""``polarid.read_image``: PNG/TIFF through the readers of the CLI."""

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

import polarid


def write_png16(path: Path, a: np.ndarray) -> None:
    """A minimal 16-bit grayscale PNG of ``a`` (uint16, (H, W)), no third-party writer."""
    h, w = a.shape

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    rows = b"".join(b"\x00" + row.astype(">u2").tobytes() for row in a)
    ihdr = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    )


def test_png16_values_as_stored(tmp_path: Path) -> None:
    a = (np.arange(6 * 5, dtype=np.uint16).reshape(5, 6) * 2000).astype(np.uint16)
    p = tmp_path / "f.png"
    write_png16(p, a)
    img = polarid.read_image(p)
    assert img.dtype == np.float32
    assert img.shape == (5, 6)
    np.testing.assert_array_equal(img, a.astype(np.float32))
    # str paths too
    np.testing.assert_array_equal(polarid.read_image(str(p)), img)


def test_real_dofp_mosaic(data_dir: Path) -> None:
    raw = polarid.read_image(data_dir / "real-dofp" / "camera_IMX250MZR.png")
    assert raw.shape == (2048, 2448)
    assert raw.dtype == np.float32
    assert 0 <= raw.min() and raw.max() <= 255
    assert np.all(raw == np.round(raw))
    assert raw.std() > 1  # an image, not a constant


def test_missing_and_bad_files(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        polarid.read_image(tmp_path / "nope.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    with pytest.raises(ValueError, match="bad.png"):
        polarid.read_image(bad)
