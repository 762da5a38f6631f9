"""One colour, line style and width per controller, so every figure of the project reads alike.

The colours are the Okabe–Ito palette (distinguishable with the common forms of
colour blindness), assigned explicitly: no two of the controllers the studies
compare share a colour. Baselines (pure pursuit and the model-based MPCs) are
drawn broken (dashed, dash-dotted, dotted), the learned controllers solid, and
the RKMPC a little wider, so a figure also reads in black and white.
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
    """Colour (hex), line style and line width (points) of one controller's lines."""

    color: str
    linestyle: str
    linewidth: float


#: The controllers learned from data (drawn solid); every other known one is a baseline.
LEARNED: frozenset[str] = frozenset({"kmpc", "rkmpc", "rkmpc-paper", "lmpc-id", "nmpc-id"})

#: Fixed style per controller name.
CONTROLLER_STYLE: dict[str, ControllerStyle] = {
    "pp": ControllerStyle(_GREY, ":", 1.3),
    "lmpc": ControllerStyle(_BLUE, "--", 1.3),
    "nmpc": ControllerStyle(_ORANGE, "-.", 1.2),
    "nmpc-dynamic": ControllerStyle(_BLACK, "-.", 1.2),
    "nmpc-acados": ControllerStyle(_ORANGE, ":", 1.2),
    "nmpc-acados-dynamic": ControllerStyle(_BLACK, ":", 1.2),
    "lmpc-id": ControllerStyle(_SKY_BLUE, "-", 1.1),
    "nmpc-id": ControllerStyle(_BLACK, "-", 1.1),
    "kmpc": ControllerStyle(_GREEN, "-", 1.1),
    "rkmpc-paper": ControllerStyle(_PURPLE, "-", 1.1),
    "rkmpc": ControllerStyle(_VERMILLION, "-", 1.8),
}


def controller_style(label: str) -> dict[str, object]:
    """Matplotlib ``color``, ``ls`` and ``lw`` of a controller label (``name`` or ``name+fault``).

    An unknown controller gets a solid line and no colour (the axes' colour cycle picks one).
    """
    style = CONTROLLER_STYLE.get(label.split("+")[0])
    if style is None:
        return {"lw": 1.1, "ls": "-"}
    return {"color": style.color, "ls": style.linestyle, "lw": style.linewidth}
