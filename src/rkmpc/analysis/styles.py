"""One colour, line style and width per controller, so every figure of the project reads alike.

The colours are the Okabe–Ito palette (distinguishable with the common forms of
colour blindness), assigned explicitly: no two of the controllers the studies
compare share a colour. Baselines (pure pursuit and the model-based MPCs) are
drawn broken (dashed, dash-dotted, dotted), the learned controllers solid, and
the RKMPC a little wider, so a figure also reads in black and white.

Lines that run close together hide each other, so each style has a drawing order (``zorder``):
the other baselines first, the LMPC over them (the nonlinear MPC's path lies on the LMPC's on
the built-in track and hid it), the learned controllers over the LMPC, the RKMPC on top;
``lmpc-id``, which stays close to the LMPC, is drawn wider than the other learned baselines.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CONTROLLER_STYLE", "LEARNED", "ControllerStyle", "controller_style"]

# Okabe & Ito (2008), "Color Universal Design".
_BLACK = "#000000"
_ORANGE = "#E69F00"
_SKY_BLUE = "#56B4E9"
_GREEN = "#009E73"
_BLUE = "#0072B2"
_VERMILLION = "#D55E00"
_PURPLE = "#CC79A7"
_GREY = "#7F7F7F"  # the palette's yellow is too pale on white; pure pursuit is grey instead


@dataclass(frozen=True)
class ControllerStyle:
    """Colour (hex), line style, line width (points) and drawing order of one controller's lines."""

    color: str
    linestyle: str
    linewidth: float
    zorder: float = 2.0


#: The controllers learned from data (drawn solid); every other known one is a baseline.
LEARNED: frozenset[str] = frozenset({"kmpc", "rkmpc", "rkmpc-paper", "lmpc-id", "nmpc-id"})

#: Fixed style per controller name.
CONTROLLER_STYLE: dict[str, ControllerStyle] = {
    "pp": ControllerStyle(_GREY, ":", 1.3, 2.0),
    "nmpc": ControllerStyle(_ORANGE, "-.", 1.2, 2.1),
    "nmpc-dynamic": ControllerStyle(_BLACK, "-.", 1.2, 2.1),
    "nmpc-acados": ControllerStyle(_ORANGE, ":", 1.2, 2.1),
    "nmpc-acados-dynamic": ControllerStyle(_BLACK, ":", 1.2, 2.1),
    "lmpc": ControllerStyle(_BLUE, "--", 1.4, 2.4),
    "kmpc": ControllerStyle(_GREEN, "-", 1.1, 2.5),
    "rkmpc-paper": ControllerStyle(_PURPLE, "-", 1.1, 2.5),
    "nmpc-id": ControllerStyle(_BLACK, "-", 1.1, 2.2),
    "lmpc-id": ControllerStyle(_SKY_BLUE, "-", 1.6, 2.6),
    "rkmpc": ControllerStyle(_VERMILLION, "-", 1.8, 3.0),
}


def controller_style(label: str) -> dict[str, object]:
    """Matplotlib ``color``, ``ls``, ``lw`` and ``zorder`` of a controller label (``name`` or ``name+fault``).

    An unknown controller gets a solid line and no colour (the axes' colour cycle picks one).
    """
    style = CONTROLLER_STYLE.get(label.split("+")[0])
    if style is None:
        return {"lw": 1.1, "ls": "-"}
    return {"color": style.color, "ls": style.linestyle, "lw": style.linewidth, "zorder": style.zorder}
