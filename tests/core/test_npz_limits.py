"""Archives declaring huge arrays are refused from their headers, before anything is unpacked."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError
from rkmpc.core.reading import MAX_NPZ_BYTES, read_npz
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.koopman.model import KoopmanModel


def _bomb(path: Path, name: str = "obs", shape: tuple[int, ...] = (2**30, 7)) -> None:
    """An ``.npz`` of a few bytes whose member ``name`` declares a float64 array of ``shape``."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(f"{name}.npy", header.getvalue() + bytes(64))
        archive.writestr("format.npy", _npy(np.int64(1)))


def _npy(value: object) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(value))
    return buffer.getvalue()


def test_read_npz_refuses_declared_arrays_beyond_the_limit(tmp_path):
    path = tmp_path / "bomb.npz"
    _bomb(path)
    assert path.stat().st_size < 10_000
    with pytest.raises(InputFileError, match=r"declares arrays of .* MiB .*limit of 512 MiB") as info:
        read_npz(path)
    assert info.value.path == path
    assert info.value.field == "obs"


def test_read_npz_refuses_members_unpacking_beyond_the_limit(tmp_path):
    path = tmp_path / "zeros.npz"
    np.savez_compressed(path, a=np.zeros(200_000))
    with pytest.raises(InputFileError, match=r"unpack to 1\.5 MiB, more than the limit of 1 MiB"):
        read_npz(path, max_bytes=2**20)
    assert read_npz(path)["a"].shape == (200_000,)


def test_the_limit_covers_data_sets_and_model_files(tmp_path):
    path = tmp_path / "bomb.npz"
    _bomb(path)
    with pytest.raises(InputFileError, match="declares arrays"):
        TransitionDataset.load(path)
    with pytest.raises(InputFileError, match="declares arrays"):
        KoopmanModel.load(path)


def test_a_single_npy_array_is_refused_unread(tmp_path):
    path = tmp_path / "one.npz"
    with path.open("wb") as handle:
        np.lib.format.write_array_header_1_0(
            handle, {"descr": "<f8", "fortran_order": False, "shape": (2**40,)}
        )
    with pytest.raises(InputFileError, match=r"a single \.npy array"):
        read_npz(path)


def test_the_limit_is_far_above_real_files():
    # A data set row is 17 float64 values: the limit holds millions of transitions.
    assert MAX_NPZ_BYTES // (17 * 8) > 3_000_000
