"""compressedDepth payloads through the binding: kp.decode_compressed_depth / kp.encode_compressed_depth.

The reference is written here: the 12-byte header packed with struct, the PNG made by OpenCV's encoder, and
compressed_depth_image_transport's inverse-depth formula with its error bound.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp

cv2 = pytest.importorskip("cv2")
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


def header(quant_a: float = 0.0, quant_b: float = 0.0) -> bytes:
    """compression format 0 (INV_DEPTH), depthQuantA, depthQuantB; little-endian."""
    return struct.pack("<iff", 0, quant_a, quant_b)


def png(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return buf.tobytes()


def quantisation(z0: float = 100.0, depth_max: float = 10.0) -> tuple[np.float32, np.float32]:
    """depthQuantA = z0 (z0 + 1), depthQuantB = 1 - depthQuantA / depth_max, in float32 as upstream computes them."""
    z = np.float32(z0)
    a = z * (z + np.float32(1.0))
    return a, np.float32(1.0) - a / np.float32(depth_max)


def random_mm(shape: tuple[int, int], seed: int, max_mm: int = 10000) -> np.ndarray:
    rng = np.random.default_rng(seed)
    mm = rng.integers(1, max_mm + 1, size=shape, dtype=np.uint16)
    mm[rng.random(shape) < 0.1] = 0  # holes
    return mm


@pytest.mark.parametrize("codec", ["png", "rvl"])
def test_uint16_round_trips_exactly(codec: str) -> None:
    mm = random_mm((37, 53), seed=1)
    fmt, data = kp.encode_compressed_depth(mm, codec=codec)
    assert fmt == f"16UC1; compressedDepth {codec}"
    assert isinstance(data, bytes) and data[:12] == header()
    out = kp.decode_compressed_depth(fmt, data)
    assert out.dtype == np.uint16 and out.shape == mm.shape
    np.testing.assert_array_equal(out, mm)


@pytest.mark.parametrize("codec", ["png", "rvl"])
@pytest.mark.parametrize("z0", [100.0, 60.0])
def test_float32_round_trips_within_the_quantisation(codec: str, z0: float) -> None:
    rng = np.random.default_rng(2)
    m = rng.uniform(0.2, 9.99, size=(30, 40)).astype(np.float32)
    specials = [np.nan, np.inf, -np.inf, 0.0, -2.0, 10.0, 25.0]
    m[0, : len(specials)] = specials
    fmt, data = kp.encode_compressed_depth(m, codec=codec, depth_quantization=z0)
    assert fmt == f"32FC1; compressedDepth {codec}"
    a, b = quantisation(z0)
    assert data[:12] == header(a, b)
    out = kp.decode_compressed_depth(fmt, data)
    assert out.dtype == np.float32 and out.shape == m.shape
    valid = np.isfinite(m) & (m > 0) & (m < 10.0)
    assert np.isnan(out[~valid]).all()
    d, back = m[valid].astype(np.float64), out[valid].astype(np.float64)
    # Truncation: the decoded depth is never nearer, and at most d'^2 / (A + d') farther (plus float rounding).
    assert (back >= d * (1 - 1e-6)).all()
    assert (back - d <= back**2 / (float(a) + back) + 1e-6 * back).all()


def test_hand_built_uint16_payload() -> None:
    mm = np.array([[0, 1, 500], [1234, 40000, 65535]], dtype=np.uint16)
    for fmt in ("16UC1; compressedDepth", "16UC1; compressedDepth png"):
        np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, header() + png(mm)), mm)


def test_hand_built_float32_payload() -> None:
    # Defaults A = 10100, B = -1009: depth = 10100 / (v + 1009).
    inverse = np.array([[0, 1, 4041, 9091, 19191]], dtype=np.uint16)
    out = kp.decode_compressed_depth("32FC1; compressedDepth png", header(10100.0, -1009.0) + png(inverse))
    assert np.isnan(out[0, 0])
    np.testing.assert_allclose(out[0, 1:], [10.0, 2.0, 1.0, 0.5], rtol=1e-6)


def test_hand_built_rvl_payload() -> None:
    # 3x1 image 0 0 5: nibbles 2 (zeros), 1 (non-zeros), a 1 (zigzag 10), packed at the top of one LE word.
    rvl = struct.pack("<IIi", 3, 1, 0x21A10000)
    np.testing.assert_array_equal(kp.decode_compressed_depth("16UC1; compressedDepth rvl", header() + rvl), [[0, 0, 5]])


@pytest.mark.parametrize("wrap", [bytes, bytearray, memoryview, lambda b: np.frombuffer(b, np.uint8)])
def test_data_may_be_any_bytes_like(wrap: Callable[[bytes], object]) -> None:
    mm = random_mm((4, 6), seed=3)
    fmt, data = kp.encode_compressed_depth(mm)
    np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, wrap(data)), mm)


def test_data_may_be_a_strided_uint8_view() -> None:
    mm = random_mm((4, 6), seed=3)
    fmt, data = kp.encode_compressed_depth(mm)
    buf = np.zeros(2 * len(data), np.uint8)
    buf[::2] = np.frombuffer(data, np.uint8)
    view = buf[::2]
    assert not view.flags.c_contiguous
    np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, view), mm)


def test_expected_shape() -> None:
    mm = random_mm((3, 4), seed=4)
    fmt, data = kp.encode_compressed_depth(mm)
    np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, data, expected_shape=(3, 4)), mm)
    with pytest.raises(ValueError, match=r"4x3 pixels: expected 640x480"):
        kp.decode_compressed_depth(fmt, data, expected_shape=(480, 640))
    with pytest.raises(ValueError, match=r"expected_shape = \(0, 4\)"):
        kp.decode_compressed_depth(fmt, data, expected_shape=(0, 4))


def test_image_transports_compressed_png_of_16_bit_depth_is_read() -> None:
    mm = random_mm((6, 9), 3)
    for fmt in ("16UC1; png compressed", " mono16 ; png compressed "):
        np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, png(mm)), mm)


@pytest.mark.parametrize(
    ("fmt", "data", "match"),
    [
        ("mono8; jpeg compressed", b"x", r"'mono8; jpeg compressed': not a depth image this package reads; it reads"),
        ("8UC1; compressedDepth", header() + b"x", r"encoding '8UC1': expected 16UC1, mono16 or 32FC1"),
        ("16UC1; compressedDepth jpeg", header() + b"x", r"codec 'jpeg': expected png or rvl"),
        ("16UC1; compressedDepth", b"\0" * 5, r"5 bytes: shorter than its 12-byte header"),
        ("16UC1; compressedDepth", header(), r"12 bytes: a header and no image"),
        ("16UC1; compressedDepth", header() + b"\xff\xd8\xff\xe0JFIF", r"not a PNG: its first bytes are ff d8 ff e0"),
        ("16UC1; compressedDepth", header() + png(np.zeros((4, 4), np.uint8)), r"8-bit grayscale.*expected 16-bit"),
        ("16UC1; compressedDepth", header() + png(np.zeros((4, 4, 3), np.uint16)), r"16-bit RGB"),
        ("16UC1; compressedDepth", header() + png(random_mm((40, 40), 5))[:300], r"PNG of 40x40 .*does not decode"),
        ("32FC1; compressedDepth", header() + png(np.ones((2, 2), np.uint16)), r"depthQuantA = 0"),
        ("32FC1; compressedDepth", png(np.ones((2, 2), np.uint16)), r"without its 12-byte header"),
        ("16UC1; compressedDepth rvl", header() + struct.pack("<II", 3, 1), r"RVL stream ends after 0 of 3 pixels"),
        ("16UC1; compressedDepth rvl", header() + struct.pack("<IIi", 3, 1, 0x70000000), r"run of 7 pixels"),
    ],
)
def test_bad_payloads_raise_value_error_saying_why(fmt: str, data: bytes, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        kp.decode_compressed_depth(fmt, data)


def test_wrong_types_raise_type_error() -> None:
    fmt, data = kp.encode_compressed_depth(np.ones((2, 2), np.uint16))
    with pytest.raises(TypeError, match="format: bytes: expected a str"):
        kp.decode_compressed_depth(fmt.encode(), data)
    with pytest.raises(TypeError, match="data: str: expected bytes"):
        kp.decode_compressed_depth(fmt, data.decode("latin-1"))
    with pytest.raises(TypeError, match="data: list"):
        kp.decode_compressed_depth(fmt, list(data))
    with pytest.raises(TypeError, match="dtype int64"):
        kp.decode_compressed_depth(fmt, np.frombuffer(data, np.uint8).astype(np.int64))
    with pytest.raises(TypeError, match=r"dtype uint8: expected uint16 \(mm\) or float32 \(m\)"):
        kp.encode_compressed_depth(np.ones((2, 2), np.uint8))
    with pytest.raises(TypeError, match="expected a numpy array"):
        kp.encode_compressed_depth([[1, 2], [3, 4]])


def test_bad_encoder_options_raise_value_error() -> None:
    img = np.ones((2, 2), np.float32)
    with pytest.raises(ValueError, match="codec 'jpeg': expected png or rvl"):
        kp.encode_compressed_depth(img, codec="jpeg")
    with pytest.raises(ValueError, match="depth_max = 0"):
        kp.encode_compressed_depth(img, depth_max=0.0)
    with pytest.raises(ValueError, match="png_level = 10"):
        kp.encode_compressed_depth(img, png_level=10)
    with pytest.raises(ValueError, match="3-D array"):
        kp.encode_compressed_depth(np.ones((2, 2, 2), np.float32))


@pytest.mark.parametrize(
    ("name", "per_metre"),
    [("tum_nyu_sun_open3d/NYU_depth_mm.png", 1000), ("tum_nyu_sun_open3d/TUM_depth.png", 5000)],
)
def test_real_frames_round_trip(name: str, per_metre: int) -> None:
    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path} is missing")
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw is not None and raw.dtype == np.uint16
    mm = (raw.astype(np.float64) * (1000.0 / per_metre)).round().astype(np.uint16)
    for codec in ("png", "rvl"):
        fmt, data = kp.encode_compressed_depth(mm, codec=codec)
        want = np.where(mm > 10000, 0, mm)  # upstream drops what lies beyond depth_max = 10 m
        np.testing.assert_array_equal(kp.decode_compressed_depth(fmt, data, expected_shape=mm.shape), want)
        metres = np.where(mm > 0, mm / 1000.0, np.nan).astype(np.float32)
        fmt32, data32 = kp.encode_compressed_depth(metres, codec=codec)
        back = kp.decode_compressed_depth(fmt32, data32)
        valid = np.isfinite(metres) & (metres < 10.0)
        assert valid.mean() > 0.5
        err = back[valid].astype(np.float64) - metres[valid]
        assert (err >= -1e-6).all() and (err <= back[valid] ** 2 / 10100.0 + 1e-5).all()
