"""Tests of rkmpc.track.loaders."""

from __future__ import annotations

from pathlib import Path as FilePath

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.track import find_self_intersection, load_centerline, load_raceline, load_track

TRACKS_DIR = FilePath(__file__).resolve().parents[2].parent / "shared" / "tracks"


def real_track_names() -> list[str]:
    folder = TRACKS_DIR / "centerlines"
    return sorted(p.stem for p in folder.glob("*.csv")) if folder.is_dir() else []


HEADER = "# x_m,y_m,w_tr_right_m,w_tr_left_m"


def circle_rows(n: int = 40, radius: float = 10.0) -> np.ndarray:
    th = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([radius * np.cos(th), radius * np.sin(th), np.full(n, 1.0), np.full(n, 1.2)])


def write_csv(path: FilePath, rows: np.ndarray | list[list[str]], header: str = HEADER) -> FilePath:
    lines = [header]
    for row in rows:
        lines.append(",".join(str(v) for v in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def expect_error(path: FilePath, words: list[str], field: str | None = None) -> InputFileError:
    with pytest.raises(InputFileError) as info:
        load_centerline(path)
    message = str(info.value)
    assert path.name in message
    for word in words:
        assert word in message, message
    if field is not None:
        assert info.value.field is not None and field in info.value.field
    return info.value


@pytest.mark.parametrize("name", real_track_names() or ["<no data>"])
def test_real_tracks_load(tracks_dir: FilePath, name: str) -> None:
    center = tracks_dir / "centerlines" / f"{name}.csv"
    race = tracks_dir / "racelines" / f"{name}.csv"
    full = load_track(center, race, scale=1.0)
    small = load_track(center, race, scale=0.1)
    assert full.name == name and small.name == name
    assert 2500.0 < full.length < 8000.0
    assert small.length == pytest.approx(0.1 * full.length, rel=1e-6)
    assert small.raceline is not None and small.reference_path is small.raceline
    assert small.raceline.length == pytest.approx(0.1 * full.raceline.length, rel=1e-6)  # type: ignore[union-attr]
    for track in (full, small):
        assert track.centerline.speed_error() < 1e-3
        smp = track.centerline.sample(track.length / 4000)
        assert find_self_intersection(smp.xy) is None
        assert track.crossings == ()  # an ordinary circuit: no bridge
        assert np.all(np.asarray(track.width_left(smp.s)) > 0)
        assert np.all(np.asarray(track.width_right(smp.s)) > 0)
    raw = np.loadtxt(center, delimiter=",", comments="#")
    assert float(small.width_right(0.0)) == pytest.approx(0.1 * raw[0, 2], rel=1e-6)
    assert float(small.width_left(0.0)) == pytest.approx(0.1 * raw[0, 3], rel=1e-6)


def test_raceline_loads(tracks_dir: FilePath) -> None:
    race = load_raceline(tracks_dir / "racelines" / "Monza.csv", scale=0.1)
    assert race.name == "Monza"
    assert 500.0 < race.length < 600.0
    assert race.speed_error() < 1e-3


def test_good_file_variants(tmp_path: FilePath) -> None:
    rows = circle_rows()
    ref = load_centerline(write_csv(tmp_path / "ref.csv", rows))
    assert ref.name == "ref"
    assert ref.length == pytest.approx(2 * np.pi * 10.0, rel=1e-3)
    assert float(ref.width_right(3.0)) == pytest.approx(1.0)
    assert float(ref.width_left(3.0)) == pytest.approx(1.2)
    # Header without '#', columns in another order, an extra column, a repeated closing point
    # and an exact consecutive duplicate: all accepted silently.
    shuffled = np.column_stack([rows[:, 3], np.zeros(len(rows)), rows[:, 1], rows[:, 0], rows[:, 2]])
    shuffled = np.vstack([shuffled[:5], shuffled[4:5], shuffled[5:], shuffled[:1]])
    other = load_centerline(
        write_csv(tmp_path / "other.csv", shuffled, header="w_tr_left_m, extra, y_m, x_m, w_tr_right_m"),
        scale=0.5,
        name="renamed",
    )
    assert other.name == "renamed"
    assert other.length == pytest.approx(0.5 * ref.length, rel=1e-9)
    assert float(other.width_left(1.0)) == pytest.approx(0.6)


def test_missing_file(tmp_path: FilePath) -> None:
    with pytest.raises(InputFileError, match=r"nothere\.csv"):
        load_centerline(tmp_path / "nothere.csv")


def test_missing_column(tmp_path: FilePath) -> None:
    path = write_csv(tmp_path / "nocol.csv", circle_rows()[:, :3], header="# x_m,y_m,w_tr_right_m")
    expect_error(path, ["missing column", "w_tr_left_m"], field="w_tr_left_m")
    race = write_csv(tmp_path / "race.csv", circle_rows()[:, :1], header="# x_m")
    with pytest.raises(InputFileError, match="y_m"):
        load_raceline(race)


def test_nan_value(tmp_path: FilePath) -> None:
    rows = circle_rows()
    rows[7, 1] = np.nan
    expect_error(write_csv(tmp_path / "nan.csv", rows), ["line 9", "not finite"], field="y_m")


def test_non_numeric_value(tmp_path: FilePath) -> None:
    rows: list[list[str]] = [[str(v) for v in r] for r in circle_rows()]
    rows[3][2] = "wide"
    expect_error(
        write_csv(tmp_path / "text.csv", rows), ["line 5", "non-numeric", "wide"], field="w_tr_right_m"
    )


def test_too_few_points(tmp_path: FilePath) -> None:
    rows = circle_rows(n=3)
    expect_error(write_csv(tmp_path / "three.csv", rows), ["at least 4", "found 3"])
    # Duplicates do not count as points.
    dup = np.vstack([rows, rows[2:3], rows[:1]])
    expect_error(write_csv(tmp_path / "dups.csv", dup), ["found 3"])


@pytest.mark.parametrize(("value", "column"), [(0.0, "w_tr_right_m"), (-0.5, "w_tr_left_m")])
def test_non_positive_width(tmp_path: FilePath, value: float, column: str) -> None:
    rows = circle_rows()
    rows[10, 2 if column == "w_tr_right_m" else 3] = value
    expect_error(write_csv(tmp_path / "width.csv", rows), ["line 12", "width must be > 0"], field=column)


def test_figure_eight_is_a_bridge_but_a_small_loop_is_refused(tmp_path: FilePath) -> None:
    # A figure-8 (the passes half a lap apart) is a track over a bridge: accepted, centre and race line.
    t = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    xy = np.column_stack([20 * np.sin(t), 10 * np.sin(2 * t)])
    rows = np.column_stack([xy, np.ones(80), np.ones(80)])
    track = load_centerline(write_csv(tmp_path / "eight.csv", rows))
    assert len(track.crossings) == 1
    race = write_csv(tmp_path / "eight_race.csv", xy, header="# x_m,y_m")
    assert load_raceline(race).length == pytest.approx(track.length, rel=1e-3)
    # A circle with a small loop in it (a line folding back on itself) is still refused.
    th = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    loop = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    circle = np.column_stack([20 * np.cos(th), 20 * np.sin(th)])
    small = np.column_stack([22 - 2 * np.cos(loop), 2 * np.sin(loop) - 0.5])
    folded = np.vstack([circle[:1], small, circle[1:]])
    rows = np.column_stack([folded, np.ones(len(folded)), np.ones(len(folded))])
    expect_error(write_csv(tmp_path / "loop.csv", rows), ["self-intersecting", "folds back"], field="x_m")
    with pytest.raises(InputFileError, match="folds back"):
        load_raceline(write_csv(tmp_path / "loop_race.csv", folded, header="# x_m,y_m"))


@pytest.mark.parametrize("shape", ["c_shape", "spiral"])
def test_unclosable_line(tmp_path: FilePath, shape: str) -> None:
    if shape == "c_shape":
        t = np.linspace(0.3, 2 * np.pi - 0.3, 60)
        xy = np.column_stack([10 * np.cos(t), 10 * np.sin(t)])
    else:
        t = np.linspace(0.0, 3 * np.pi, 120)
        xy = np.column_stack([(2 + t) * np.cos(t), (2 + t) * np.sin(t)])
    rows = np.column_stack([xy, np.ones(len(xy)), np.ones(len(xy))])
    expect_error(write_csv(tmp_path / f"{shape}.csv", rows), ["not closable"], field="x_m")


def test_bad_scale(tmp_path: FilePath) -> None:
    path = write_csv(tmp_path / "ok.csv", circle_rows())
    for scale in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ParameterError, match="scale"):
            load_centerline(path, scale=scale)


def test_empty_file(tmp_path: FilePath) -> None:
    path = tmp_path / "empty.csv"
    path.write_text("\n")
    with pytest.raises(InputFileError, match="header"):
        load_centerline(path)


def test_find_self_intersection() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert find_self_intersection(square) is None
    bowtie = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    assert find_self_intersection(bowtie) == (0, 2)
    folded = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    assert find_self_intersection(folded) is not None


def test_a_byte_order_mark_is_not_part_of_the_header(tmp_path: FilePath) -> None:
    """Excel's 'CSV UTF-8' starts the file with a byte-order mark; the header still reads."""
    plain = load_centerline(
        write_csv(tmp_path / "plain.csv", circle_rows(), header="x_m,y_m,w_tr_right_m,w_tr_left_m")
    )
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + (tmp_path / "plain.csv").read_bytes())
    assert load_centerline(path).length == pytest.approx(plain.length)
