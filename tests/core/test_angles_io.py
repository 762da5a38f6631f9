"""The ground floor: angle wrapping, atomic files, .npz reading and version records."""

from __future__ import annotations

import json
import math
import os
import platform
import zipfile
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.angles import TWO_PI, branch_shift, wrap_angle, wrap_scalar
from rkmpc.core.errors import InputFileError
from rkmpc.core.io import atomic_write, write_json_atomic, write_text_atomic
from rkmpc.core.reading import read_npz
from rkmpc.core.versions import RESULT_PACKAGES, package_version, versions

PI = math.pi
EDGES = [
    0.0,
    -0.0,
    PI,
    -PI,
    2 * PI,
    -2 * PI,
    3 * PI,
    -3 * PI,
    PI / 2,
    -PI / 2,
    1e-300,
    -1e-300,
    5e-324,
    1e6,
    -1e6,
    1e17,
    -1e17,
    1e300,
    -1e300,
    1.7976931348623157e308,
]


# ---------------------------------------------------------------------------- angles


def test_wrap_angle_range_and_edges():
    assert wrap_angle(PI) == PI
    assert wrap_angle(-PI) == PI
    assert wrap_angle(3 * PI) == PI
    assert wrap_angle(-3 * PI) == PI
    assert wrap_angle(2 * PI) == 0.0
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(PI / 2) == PI / 2
    assert wrap_angle(-PI / 2) == -PI / 2
    assert wrap_angle(PI + 0.5) == pytest.approx(-PI + 0.5)
    assert wrap_angle(-PI - 0.5) == pytest.approx(PI - 0.5)
    assert wrap_angle(7.0) == pytest.approx(7.0 - TWO_PI)


def test_wrap_angle_types():
    assert type(wrap_angle(1.0)) is float
    assert type(wrap_angle(np.float64(4.0))) is float
    assert type(wrap_angle(7)) is float
    assert type(wrap_angle(np.array(4.0))) is float
    out = wrap_angle(np.array([[0.0, 4.0], [-4.0, 10.0]]))
    assert isinstance(out, np.ndarray) and out.shape == (2, 2) and out.dtype == np.float64
    np.testing.assert_allclose(out, [[0.0, 4.0 - TWO_PI], [TWO_PI - 4.0, 10.0 - 4 * PI]])
    assert wrap_angle([1.0, 8.0]).tolist() == pytest.approx([1.0, 8.0 - TWO_PI])
    assert wrap_angle(np.array([])).shape == (0,)


def test_wrap_angle_is_elementwise():
    rng = np.random.default_rng(1)
    a = rng.uniform(-50, 50, size=(7, 5))
    out = wrap_angle(a)
    for idx in np.ndindex(a.shape):
        assert out[idx] == wrap_angle(float(a[idx]))


@pytest.mark.parametrize("scale", [1e-3, 1.0, PI, 10.0, 1e3, 1e6, 1e12, 1e300])
def test_wrap_angle_range_and_equivalence_random(scale):
    rng = np.random.default_rng(round(math.log10(scale) * 7) + 100)
    a = rng.uniform(-scale, scale, size=100_000)
    w = wrap_angle(a)
    assert (w > -PI).all() and (w <= PI).all()
    # The wrapped angle differs from the input by a multiple of 2 pi (checked where that is resolvable).
    small = np.abs(a) < 1e3
    k = (a[small] - w[small]) / TWO_PI
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    scalar = np.array([wrap_scalar(float(v)) for v in a])
    np.testing.assert_array_equal(scalar, w)


@pytest.mark.parametrize("angle", EDGES)
def test_wrap_scalar_equals_wrap_angle_on_edges(angle):
    assert wrap_scalar(angle) == wrap_angle(angle)
    assert -PI < wrap_scalar(angle) <= PI


@pytest.mark.parametrize("angle", EDGES)
def test_wrap_scalar_equals_wrap_angle_on_edges_as_arrays(angle):
    assert wrap_angle(np.array([angle]))[0] == wrap_scalar(angle)


@pytest.mark.parametrize("ulps", [1, 3])
def test_wrap_just_above_pi(ulps):
    angle = PI
    for _ in range(ulps):
        angle = math.nextafter(angle, math.inf)
    assert -PI < wrap_angle(angle) <= PI
    assert wrap_scalar(angle) == wrap_angle(angle)


def test_wrap_of_nan_is_nan():
    assert math.isnan(wrap_angle(math.nan))
    assert math.isnan(wrap_scalar(math.nan))


def test_branch_shift():
    assert branch_shift(0.0) == 0.0
    assert branch_shift(3.0) == 0.0
    assert branch_shift(-3.0) == 0.0
    assert branch_shift(3.3) == TWO_PI
    assert branch_shift(-3.3) == -TWO_PI
    assert branch_shift(6.0) == TWO_PI
    assert branch_shift(13.0) == 2 * TWO_PI
    assert branch_shift(-100.0) == -16 * TWO_PI
    rng = np.random.default_rng(5)
    for a in rng.uniform(-1e4, 1e4, size=1000):
        shift = branch_shift(float(a))
        assert abs(a - shift) <= PI + 1e-9
        assert shift == TWO_PI * round(shift / TWO_PI)


def test_branch_shift_keeps_a_sequence_continuous():
    headings = np.unwrap(np.linspace(0, 40, 200) % TWO_PI)  # a car turning many times
    shifted = headings - branch_shift(float(headings[120]))
    np.testing.assert_allclose(np.diff(shifted), np.diff(headings))
    assert abs(shifted[120]) <= PI


# ---------------------------------------------------------------------------- atomic files


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_atomic_write_success(tmp_path):
    path = tmp_path / "deep" / "folder" / "a.txt"
    with atomic_write(path) as handle:
        handle.write("line 1\nline 2\n")
        # Nothing at the destination until the block ends.
        assert not path.exists()
    assert path.read_text() == "line 1\nline 2\n"
    assert [p.name for p in path.parent.iterdir()] == ["a.txt"]
    assert path.stat().st_mode & 0o777 == 0o666 & ~_umask()


def test_atomic_write_binary_replaces_the_old_file(tmp_path):
    path = tmp_path / "b.bin"
    path.write_bytes(b"old")
    with atomic_write(path, "wb", suffix=".png") as handle:
        handle.write(b"\x00\x01new")
        # The temporary file sits beside the destination, hidden, with the asked suffix.
        temporary = sorted(p.name for p in tmp_path.iterdir() if p.name != "b.bin")
        assert len(temporary) == 1
        assert temporary[0].startswith(".b.bin.") and temporary[0].endswith(".png")
        assert path.read_bytes() == b"old"
    assert path.read_bytes() == b"\x00\x01new"
    assert [p.name for p in tmp_path.iterdir()] == ["b.bin"]


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_atomic_write_failure_keeps_the_old_file(tmp_path, error):
    path = tmp_path / "a.txt"
    path.write_text("old content")
    with pytest.raises(error), atomic_write(path) as handle:
        handle.write("half of the new")
        raise error("boom")
    assert path.read_text() == "old content"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_atomic_write_failure_without_old_file(tmp_path):
    path = tmp_path / "new.txt"
    with pytest.raises(ValueError, match="boom"), atomic_write(path):
        raise ValueError("boom")
    assert list(tmp_path.iterdir()) == []


def test_write_text_atomic(tmp_path):
    path = tmp_path / "t.md"
    write_text_atomic(path, "a\r\nb\n")
    assert path.read_bytes() == b"a\r\nb\n"  # written as given, no newline translation
    write_text_atomic(path, "c")
    assert path.read_text() == "c"
    assert [p.name for p in tmp_path.iterdir()] == ["t.md"]


def test_write_json_atomic_with_numpy_values(tmp_path):
    path = tmp_path / "r.json"
    payload = {
        "f": np.float64(1.5),
        "f32": np.float32(0.25),
        "i": np.int64(7),
        "b": np.bool_(True),
        "arr": np.arange(3),
        "mat": np.eye(2),
        "t": (1, 2),
        "p": Path("x/y"),
        "nan": math.nan,
    }
    write_json_atomic(path, payload)
    text = path.read_text()
    assert text.endswith("\n")
    back = json.loads(text)
    assert back["f"] == 1.5 and back["f32"] == 0.25 and back["i"] == 7 and back["b"] is True
    assert back["arr"] == [0, 1, 2] and back["mat"] == [[1.0, 0.0], [0.0, 1.0]]
    assert back["t"] == [1, 2] and back["p"] == "x/y"
    assert math.isnan(back["nan"])
    assert list(back) == list(payload)  # key order kept


def test_write_json_atomic_refuses_unknown_objects_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "r.json"
    write_json_atomic(path, {"ok": 1})
    with pytest.raises(TypeError, match="object"):
        write_json_atomic(path, {"bad": object()})
    assert json.loads(path.read_text()) == {"ok": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


# ---------------------------------------------------------------------------- read_npz


def _npz(path: Path) -> dict[str, np.ndarray]:
    arrays = {"a": np.arange(5000, dtype=float), "b": np.eye(3)}
    np.savez_compressed(path, **arrays)
    return arrays


def test_read_npz_reads_every_array(tmp_path):
    path = tmp_path / "d.npz"
    arrays = _npz(path)
    out = read_npz(path)
    assert sorted(out) == ["a", "b"]
    for key, value in arrays.items():
        np.testing.assert_array_equal(out[key], value)


def test_read_npz_refuses_a_non_zip_file(tmp_path):
    path = tmp_path / "d.npz"
    path.write_text("x,y\n1,2\n")
    with pytest.raises(InputFileError, match=r"d\.npz: not a readable \.npz archive") as info:
        read_npz(path)
    assert info.value.path == path


def test_read_npz_refuses_a_single_npy_file(tmp_path):
    path = tmp_path / "d.npz"
    with path.open("wb") as handle:
        np.save(handle, np.arange(3))
    with pytest.raises(InputFileError, match=r"not an .npz archive \(a single .npy array\)"):
        read_npz(path)


@pytest.mark.parametrize("keep", [0.3, 0.6, 0.95])
def test_read_npz_refuses_a_truncated_archive(tmp_path, keep):
    path = tmp_path / "d.npz"
    _npz(path)
    data = path.read_bytes()
    path.write_bytes(data[: int(keep * len(data))])
    with pytest.raises(InputFileError, match="corrupted or truncated") as info:
        read_npz(path)
    assert info.value.path == path


def test_read_npz_refuses_a_corrupted_member(tmp_path):
    path = tmp_path / "d.npz"
    _npz(path)
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("a.npy")
    middle = info.header_offset + 30 + len(info.filename) + info.compress_size // 2
    data[middle : middle + 16] = bytes(16)
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="corrupted or truncated"):
        read_npz(path)


def test_read_npz_missing_file(tmp_path):
    with pytest.raises(InputFileError, match=r"absent\.npz"):
        read_npz(tmp_path / "absent.npz")


def test_read_npz_refuses_pickled_objects(tmp_path):
    path = tmp_path / "d.npz"
    np.savez(path, obj=np.array([{"a": 1}], dtype=object))
    with pytest.raises(InputFileError, match=r"d\.npz"):
        read_npz(path)


# ---------------------------------------------------------------------------- versions


def test_versions():
    v = versions()
    assert next(iter(v)) == "python"
    assert v["python"] == platform.python_version()
    assert v["numpy"] == np.__version__
    assert v["rkmpc"] not in ("", "not installed")
    assert set(RESULT_PACKAGES) <= set(v)
    assert all(isinstance(value, str) for value in v.values())


def test_versions_extra():
    import matplotlib

    v = versions(extra=["matplotlib", "no-such-package-rkmpc-test"])
    assert v["matplotlib"] == matplotlib.__version__
    assert v["no-such-package-rkmpc-test"] == "not installed"
    assert list(v)[-2:] == ["matplotlib", "no-such-package-rkmpc-test"]
    assert "matplotlib" not in versions()


def test_package_version_missing_text():
    assert package_version("no-such-package-rkmpc-test") == "not installed"
    assert package_version("no-such-package-rkmpc-test", missing="0.0.0") == "0.0.0"
    assert package_version("numpy") == np.__version__
