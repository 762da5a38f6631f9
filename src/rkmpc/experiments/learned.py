"""One track, every controller: collect LMPC laps, learn, drive, measure.

This is the experiment of the paper's Table I for one track: two laps of LMPC
data train the residual models and identify ``lmpc-id``; the KMPC model,
trained on random-excitation data of the car, is given (it does not depend
on the track). Every controller then drives one flying lap from the same start.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from rkmpc.control.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC, ResidualMPCConfig
from rkmpc.experiments.runner import RunSpec, run_controller, versions
from rkmpc.learning.augmentation import AugmentConfig
from rkmpc.learning.collect import collect
from rkmpc.learning.identification import identify
from rkmpc.learning.koopman import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, default_model_options, train_model
from rkmpc.scenario import load_scenario

#: Controllers of the learned comparison, in table order.
LEARNED_CONTROLLERS = ("lmpc", "lmpc-id", "rkmpc-paper", "rkmpc", "kmpc")

#: Residual MPC settings of the two RKMPC variants (tuned on builtin, Monza and Budapest, then fixed).
RKMPC_CONFIG = ResidualKoopmanMPC.default_config
RKMPC_PAPER_CONFIG = PaperResidualKoopmanMPC.default_config


@dataclass(frozen=True)
class TrackStudy:
    """Settings of :func:`evaluate_track`.

    Parameters
    ----------
    track : str
        Built-in name or centre-line CSV path.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    controllers : sequence of str
        Controllers to drive.
    laps : int
        Laps of LMPC data to learn from.
    seed : int
        Seed of the data collection and of training.
    kmpc_model : str or None
        Path of a trained ``koopman`` model; ``kmpc`` is skipped without it.
    rkmpc : ResidualMPCConfig
        Residual MPC settings of ``rkmpc``.
    rkmpc_paper : ResidualMPCConfig
        Residual MPC settings of ``rkmpc-paper``.
    """

    track: str
    scale: float | None = None
    vehicle: str = "f1tenth"
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    laps: int = 2
    seed: int = 0
    kmpc_model: str | None = None
    rkmpc: ResidualMPCConfig = field(default_factory=lambda: RKMPC_CONFIG)
    rkmpc_paper: ResidualMPCConfig = field(default_factory=lambda: RKMPC_PAPER_CONFIG)


def evaluate_track(study: TrackStudy) -> dict[str, Any]:
    """Learn on ``study.laps`` LMPC laps of the track and drive every controller one lap.

    Returns
    -------
    dict
        ``track``, ``controllers`` (metrics per controller), ``training``
        (sample counts, fit times, identified parameters) and ``config``.
    """
    scenario = load_scenario(study.track, scale=study.scale, vehicle=study.vehicle)
    wheelbase = scenario.vehicle.wheelbase
    data = collect(scenario, controller="lmpc", laps=study.laps, seed=study.seed)
    training: dict[str, Any] = {"raw_samples": len(data), "data_outcome": data.metadata["outcome"]}
    options: dict[str, dict[str, Any]] = {}
    names = list(study.controllers)
    if "lmpc-id" in names:
        ident = identify(data, wheelbase)
        training["identified"] = asdict(ident)
        options["lmpc-id"] = {"model": ident}
    for name, kind, cfg in (("rkmpc", "residual", study.rkmpc), ("rkmpc-paper", "paper", study.rkmpc_paper)):
        if name in names:
            model, report = train_model(
                data,
                wheelbase,
                TrainConfig(
                    kind=kind,
                    augment=AugmentConfig(seed=study.seed),
                    model=default_model_options(kind, seed=study.seed),
                ),
            )
            training[kind] = asdict(report)
            options[name] = {"model": model, "config": cfg}
    if "kmpc" in names:
        if study.kmpc_model is None:
            names.remove("kmpc")
        else:
            options["kmpc"] = {"model": KoopmanModel.load(Path(study.kmpc_model))}
    results = {}
    for name in names:
        _, metrics = run_controller(
            scenario, RunSpec(name, seed=study.seed), controller_options=options.get(name)
        )
        results[name] = metrics
    return {
        "track": scenario.track.name,
        "controllers": results,
        "training": training,
        "config": {
            "scenario": scenario.describe(),
            "seed": study.seed,
            "laps_of_data": study.laps,
            "rkmpc": asdict(study.rkmpc),
            "rkmpc_paper": asdict(study.rkmpc_paper),
            "kmpc_model": study.kmpc_model,
            "versions": versions(),
        },
    }
