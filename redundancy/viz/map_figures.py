"""Heatmaps of a design map (`redundancy.study.maps`): per objective, the improved start's gain
over the default start (%, where both keep the strokes), the best initial value of each held
actuator and the share of feasible problems, over the map's first two axes (workspace start
coordinates, or segments and design parameters). Where the map varies more than two, each cell
is the mean over the others, as its title says.

Figures read the table; they compute nothing of their own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from redundancy.study.families import Design, MapFamily
from redundancy.study.maps import UNITS, axes_of
from redundancy.viz.plots import pyplot, suptitled, write_pngs

PANELS = (("gain_pct", "gain over the default start (%)"), ("feasible", "feasible share"))


def map_figure(table, family: MapFamily, objective: str):
    """Heatmaps side by side for ``objective``: gain %, the best initial value of each held
    actuator (one panel each), feasible share."""
    plt = pyplot()
    rows = table[table["objective"] == objective].copy()
    # a gain is only one where both starts keep the strokes: elsewhere it has no meaning
    rows["gain_pct"] = rows["gain_pct"].where(rows["feasible"] & rows["default_feasible"])
    rows["feasible"] = rows["feasible"].astype(float)
    axes_names = axes_of(rows, family) or ["segment"]
    x, y = axes_names[0], (axes_names[1] if len(axes_names) > 1 else None)
    actuators = family.robot_for(Design()).actuators
    best = [(f"best_{h}", f"best initial {h} ({actuators[h].unit})") for h in family.held]
    panels = (PANELS[0], *best, PANELS[1])
    figure, panes = plt.subplots(
        1, len(panels), figsize=(5 * len(panels), 4.6), constrained_layout=True
    )
    for pane, (column, label) in zip(panes, panels):
        grid = (
            rows.pivot_table(index=y, columns=x, values=column, aggfunc="mean", dropna=False)
            if y
            else rows.groupby(x)[column].mean().to_frame().T
        )
        values = grid.to_numpy(dtype=float)
        image = pane.imshow(values, origin="lower", aspect="auto", cmap="viridis")
        pane.set_xticks(range(grid.shape[1]), _ticks(grid.columns), rotation=45)
        pane.set_yticks(range(grid.shape[0]), _ticks(grid.index))
        pane.set_xlabel(_label(x))
        pane.set_ylabel(_label(y) if y else "")
        pane.set_title(label)
        bar = figure.colorbar(image, ax=pane)
        finite = values[np.isfinite(values)]
        if column == "feasible":  # a share: its whole range, whatever the map found
            image.set_clim(0, 1)
        elif finite.size and finite.min() == finite.max():  # one value: one tick, no range
            image.set_clim(finite[0] - 1, finite[0] + 1)
            bar.set_ticks([finite[0]], labels=[_tick(finite[0])])
    rest = axes_names[2:]
    suffix = f" (mean over {', '.join(rest)})" if rest else ""
    suptitled(
        figure,
        f"{family.name}: {objective} objective{suffix}; blank: no value (a gain needs both "
        "starts feasible)",
    )
    return figure


def _label(axis: str) -> str:
    """An axis's name with its unit: a workspace start coordinate in m, a design parameter in
    its own."""
    unit = "m" if axis.startswith("start_") else UNITS.get(axis)
    return f"{axis} ({unit})" if unit else axis


def _tick(value, digits: int = 3) -> str:
    return f"{value:.{digits}g}" if isinstance(value, float) else str(value)


def _ticks(values) -> list[str]:
    """The labels of an axis's values: 3 significant digits, more where two would read alike
    (3.501 and 3.502 m are not both 3.5)."""
    values = list(values)
    for digits in range(3, 16):
        labels = [_tick(v, digits) for v in values]
        if len(set(labels)) == len(labels):
            return labels
    return labels


def write_map_figures(table, family: MapFamily, folder: Path) -> list[Path]:
    """Write one heatmap figure per objective into ``folder``; return their paths."""
    figures = {f"map_{o}.png": map_figure(table, family, o) for o in family.objectives}
    return write_pngs(figures, folder, dpi=100)
