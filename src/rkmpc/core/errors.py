"""Exceptions raised by rkmpc for bad user input."""

from __future__ import annotations

from pathlib import Path


class RkmpcError(Exception):
    """Base class of the errors rkmpc raises on purpose."""


class InputFileError(RkmpcError, ValueError):
    """A user-supplied file is unreadable or its content is invalid.

    Parameters
    ----------
    path : str or Path
        The offending file.
    problem : str
        What is wrong, in words.
    field : str, optional
        The column, key or field at fault, where one is.
    """

    def __init__(self, path: str | Path, problem: str, field: str | None = None) -> None:
        self.path = Path(path)
        self.field = field
        self.problem = problem
        where = f"{self.path}"
        if field is not None:
            where += f" [{field}]"
        super().__init__(f"{where}: {problem}")


class BagError(InputFileError):
    """A recorded bag (ROS 1 ``.bag``, ROS 2 sqlite3 or MCAP) cannot be read or its data are unusable.

    Parameters
    ----------
    path : str or Path
        The bag (a ``.bag`` file or a ROS 2 bag folder).
    problem : str
        What is wrong, in words.
    topic : str, optional
        The topic at fault, where one is.
    field : str, optional
        The message field at fault (``"drive.speed"``, ``"header.stamp"``), where one is.
    """

    def __init__(
        self, path: str | Path, problem: str, topic: str | None = None, field: str | None = None
    ) -> None:
        self.topic = topic
        self.message_field = field
        where = [part for part in (topic, field) if part is not None]
        super().__init__(path, problem, ", ".join(where) if where else None)


class NotLearnedError(RkmpcError):
    """A model was fitted but is refused: it predicts its own held-out data worse than the model it corrects.

    Parameters
    ----------
    source : str
        The data it was learned from (a file, or what made the laps).
    kind : str
        The model kind (``residual``, ...).
    reason : str
        The figures that refuse it, in words.
    """

    def __init__(self, source: str, kind: str, reason: str) -> None:
        self.source = source
        self.kind = kind
        self.reason = reason
        super().__init__(f"{source}: the {kind} model learned from it is refused: {reason}")


class OutputError(RkmpcError):
    """An output file or folder cannot be written as asked (in use, a folder for a file, ...)."""


def raise_if_interrupted(exc: BaseException) -> None:
    """Raise :class:`KeyboardInterrupt` when ``exc`` was caused by one (Ctrl-C inside a C solver).

    CasADi turns a Ctrl-C that arrives during an IPOPT solve into a ``SystemError`` whose cause
    (or context) chain ends in the :class:`KeyboardInterrupt`; code that catches every solver
    error calls this first, so that Ctrl-C still ends the run.
    """
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        seen.add(id(current))
        current = current.__cause__ or current.__context__


class MissingPackageError(RkmpcError, ImportError):
    """An optional package a feature needs is not installed (the message says how to install it)."""


class ParameterError(RkmpcError, ValueError):
    """A parameter set failed validation (names the parameter and the problem)."""


class IdentificationWarning(UserWarning):
    """Identification kept a nominal or bounded value because the data did not support a fit."""


class ContractError(RkmpcError, ValueError):
    """A data set or a model is used with another car, period or track scale than it was made with.

    Parameters
    ----------
    source : str
        The file (or object) at fault.
    problem : str
        Every field that differs, with both values.
    mismatch : bool
        Whether using it anyway can be asked for: the message then ends with how, for a library
        user (``allow_mismatch=True``); the command line says its flag instead
        (:meth:`for_command_line`).
    """

    LIBRARY_HINT = "pass allow_mismatch=True to use it anyway"
    COMMAND_LINE_HINT = "give --allow-mismatch to use it anyway"

    def __init__(self, source: str, problem: str, *, mismatch: bool = False) -> None:
        self.source = source
        self.problem = problem
        self.mismatch = mismatch
        super().__init__(f"{problem} ({self.LIBRARY_HINT})" if mismatch else problem)

    def for_command_line(self) -> str:
        """The message with the command line's flag (``--allow-mismatch``) as the way out."""
        return f"{self.problem} ({self.COMMAND_LINE_HINT})" if self.mismatch else self.problem


class ContractWarning(UserWarning):
    """A data set or a model used, on request, with another car, period or scale than it was made with."""


class PlantIntegrationError(RkmpcError, RuntimeError):
    """A simulated car could not integrate its dynamics over a step.

    The closed loop (:func:`rkmpc.sim.closed_loop.simulate`) ends the run with the outcome
    ``"plant_failure"`` and records the message, rather than letting it end a comparison.

    Parameters
    ----------
    message : str
        What failed, where and when.
    time : float
        Simulation time (s) at the start of the step that failed.
    """

    def __init__(self, message: str, time: float) -> None:
        self.time = float(time)
        super().__init__(message)
