"""The results of :func:`rkmpc.experiments.evaluate.evaluate`: a row per model and horizon."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = ["Evaluation", "EvaluationRow", "evaluation_row"]


@dataclass(frozen=True, kw_only=True)
class EvaluationRow:
    """One model at one horizon: the errors of its predictions (SI units) over ``samples`` starts.

    ``model`` is the model's kind (``kinematic`` for the nominal model, ``residual``, ``identified``,
    ``koopman``, ...), ``file`` the name it was given (its file's; None for the nominal model).
    """

    model: str
    file: str | None
    horizon_steps: int
    horizon_s: float
    samples: int
    position_mean_m: float
    position_p95_m: float
    heading_mean_rad: float
    speed_mean_m_s: float


@dataclass(frozen=True, kw_only=True)
class Evaluation:
    """What :func:`evaluate` found: one row per model and horizon, and how the truth was made."""

    rows: list[EvaluationRow]
    transitions: int
    starts: int
    dt: float
    truth: str
    source: str | None
    models: dict[str, str]
    exact_inputs: list[EvaluationRow] = field(default_factory=list)

    def row(self, model: str, horizon: int, *, kind: str | None = None) -> EvaluationRow:
        """The row of ``model`` (a kind, or a file's name where two files have one kind) at ``horizon``;
        ``kind`` picks among a file's rows (``residual`` or ``residual+drift``)."""
        found = [
            row
            for row in self.rows
            if row.horizon_steps == horizon
            and (row.file == model or row.model == model)
            and (kind is None or row.model == kind)
        ]
        if len(found) == 1:
            return found[0]
        by_file = [row for row in found if row.file == model]
        by_kind = [row for row in found if row.model == model]
        for named in (by_file, by_kind):
            if len(named) == 1:
                return named[0]
        if len({row.model for row in found}) > 1:
            kinds = ", ".join(row.model for row in found)
            raise ParameterError(f"{len(found)} rows of {model!r} ({kinds}): name the kind")
        if found:
            files = ", ".join(str(row.file) for row in found)
            raise ParameterError(f"{len(found)} models of kind {model!r} ({files}): name one by its file")
        raise ParameterError(f"no evaluation of {model!r} at {horizon} steps")

    def label(self, row: EvaluationRow) -> str:
        """What to call the row's model: its kind, or its file's name where two files have one kind."""
        same = {r.file for r in self.rows if r.model == row.model}
        return row.model if len(same) == 1 else f"{row.model} ({row.file})"

    def to_json(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "transitions": self.transitions,
            "starts": self.starts,
            "dt": self.dt,
            "truth": self.truth,
            "models": dict(self.models),
            "rows": [asdict(row) for row in self.rows],
            "exact_inputs": [asdict(row) for row in self.exact_inputs],
        }

    def figure(self) -> Any:
        """Position and heading error against the horizon, one line per model and the exact inputs."""
        from rkmpc.analysis.prediction_plots import plot_prediction_errors

        labels = {self.label(row): (row.file or row.model, row.model) for row in self.rows}
        steps = sorted({row.horizon_steps for row in self.rows})
        exact = {row.horizon_steps: row for row in self.exact_inputs}

        def series(field: str) -> dict[str, list[float]]:
            out = {
                label: [float(getattr(self.row(key, h, kind=kind), field)) for h in steps]
                for label, (key, kind) in labels.items()
            }
            if exact:  # made by evaluate at the same horizons as the models
                out["exact inputs"] = [float(getattr(exact[h], field)) for h in steps]
            return out

        return plot_prediction_errors(
            [h * self.dt for h in steps],
            series("position_mean_m"),
            series("position_p95_m"),
            series("heading_mean_rad"),
            f"open-loop prediction of {self.source or 'recorded driving'}",
        )

    def to_markdown(self) -> str:
        """One row per model and horizon, with the ratio of its errors to the kinematic model's."""
        lines = [
            f"Open-loop prediction of {self.transitions} recorded transitions ({self.starts} starts, "
            f"dt {self.dt:g} s); truth: {self.truth}.",
            "",
            "| model | file | steps | s | position mean (m) | p95 (m) | vs kinematic | heading (rad) | "
            "speed (m/s) |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in self.rows:
            lines.append(
                f"| {r.model} | {r.file or '-'} | {r.horizon_steps} | {r.horizon_s:.2f} | "
                f"{r.position_mean_m:.4f} | "
                f"{r.position_p95_m:.4f} | {self._vs_kinematic(r)} | {r.heading_mean_rad:.4f} | "
                f"{r.speed_mean_m_s:.3f} |"
            )
        if self.exact_inputs:
            cells = [f"{r.horizon_steps} steps {self._vs_kinematic(r)}" for r in self.exact_inputs]
            lines += [
                "",
                "Exact inputs (the kinematic model driven by the inputs that reproduce each recorded "
                "step's distance and heading change: a perfect model of the residual's form; position "
                "mean / p95 vs kinematic): " + ", ".join(cells) + ".",
            ]
        return "\n".join(lines) + "\n"

    def _vs_kinematic(self, r: EvaluationRow) -> str:
        """``mean / p95``: the row's position errors over the kinematic model's at its horizon."""
        base = self.row("kinematic", r.horizon_steps)
        ratio = r.position_mean_m / base.position_mean_m if base.position_mean_m > 0 else math.nan
        p95 = r.position_p95_m / base.position_p95_m if base.position_p95_m > 0 else math.nan
        return f"{ratio:.2f} / {p95:.2f}"


def evaluation_row(
    kind: str,
    name: str | None,
    horizon: int,
    dt: float,
    errors: tuple[np.ndarray, np.ndarray, np.ndarray],
    samples: int,
) -> EvaluationRow:
    """The row of one model at ``horizon`` steps from its errors: position (m), heading (rad) and
    speed (m/s), each of shape (starts, horizons)."""
    position, heading, speed = (e[:, horizon - 1] for e in errors)
    return EvaluationRow(
        model=kind,
        file=name,
        horizon_steps=horizon,
        horizon_s=horizon * dt,
        samples=int(samples),
        position_mean_m=float(np.mean(position)),
        position_p95_m=float(np.percentile(position, 95)),
        heading_mean_rad=float(np.mean(heading)),
        speed_mean_m_s=float(np.nanmean(speed)),
    )
