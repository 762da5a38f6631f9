"""Issue 27's probe: inputs that made a run hang (a huge horizon, a FIFO or an endless file as the
car file, an endless environment step). Each runs within a guard: a hang fails the case."""

from __future__ import annotations

import os

from probe_cases import CLEAR_ERROR, Evidence, Probe, case, cli_error, raises, within

GROUP = "hangs (issue 27)"
#: The guard of each case (s): against a hang, never what is measured.
GUARD = 120.0


def _car_file(probe: Probe, text: str) -> str:
    path = probe.path("car.toml")
    path.write_text(text)
    return str(path)


@case(
    "hang.horizon_10000",
    GROUP,
    "[controllers.lmpc] horizon = 10000 in a car file (ran for 300 s, 9 GB, Ctrl-C ignored)",
    CLEAR_ERROR,
    problem="hang",
)
def horizon_10000(probe: Probe) -> Evidence:
    car = _car_file(probe, "[controllers.lmpc]\nhorizon = 10000\n")
    out = probe.path("o")
    with within(GUARD, "a run with horizon 10000"):
        evidence = cli_error(
            probe, ["run", "--controller", "lmpc", "--config", car, "--out", str(out)], "car.toml", "horizon"
        )
    assert "from 2 to 200" in evidence.message and not out.exists()
    assert not [p for p in probe.tmp.iterdir() if p.name.startswith(".o.")]  # no hidden folder left
    return evidence


@case(
    "hang.config_fifo",
    GROUP,
    "--config naming a FIFO (blocked with no output): refused at once, saying what it is",
    CLEAR_ERROR,
    problem="hang",
)
def config_fifo(probe: Probe) -> Evidence:
    fifo = probe.path("car.toml")
    os.mkfifo(fifo)
    with within(GUARD, "reading a FIFO as the car file"):
        return cli_error(
            probe,
            ["run", "--controller", "lmpc", "--config", str(fifo), "--out", str(probe.path("o"))],
            "car.toml",
            "a FIFO (named pipe), not a regular file",
        )


@case(
    "hang.config_endless",
    GROUP,
    "--config naming a file that never ends (/dev/zero) or one over 1 MiB: refused unread",
    CLEAR_ERROR,
    problem="hang",
)
def config_endless(probe: Probe) -> Evidence:
    big = probe.path("big.toml")
    big.write_text("# padding\n" + "#" * (1 << 20) + "\n")
    with within(GUARD, "reading an endless car file"):
        cli_error(
            probe, ["run", "--controller", "pp", "--config", str(big), "--out", str(probe.path("o"))], "bytes"
        )
        return cli_error(
            probe,
            ["run", "--controller", "pp", "--config", "/dev/zero", "--out", str(probe.path("o"))],
            "/dev/zero: a character device, not a regular file",
        )


@case(
    "hang.weights_1e300",
    GROUP,
    "heading_weight = 1e300 (every step fell back, 'numerical'): refused naming the field and the bound",
    CLEAR_ERROR,
    problem="unclear",
)
def weights_1e300(probe: Probe) -> Evidence:
    car = _car_file(probe, "[controllers.lmpc]\nheading_weight = 1e300\n")
    return cli_error(
        probe,
        ["run", "--controller", "lmpc", "--config", car, "--out", str(probe.path("o"))],
        "[controllers.lmpc.heading_weight]",
        "[0, 1e+08]",
    )


@case(
    "hang.env_timestep",
    GROUP,
    "F1TenthEnvConfig(timestep=1000) (a 1000 s step took 4 s, larger ones an hour): refused",
    CLEAR_ERROR,
    problem="hang",
)
def env_timestep(_: Probe) -> Evidence:
    from rkmpc.envs.f1tenth import F1TenthEnvConfig

    with within(GUARD, "building an environment config"):
        return raises(lambda: F1TenthEnvConfig(timestep=1000.0), "timestep", "1000")
