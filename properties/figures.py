"""What the figure tests read of a drawn figure beyond its data: where a legend sits."""

from __future__ import annotations

from matplotlib.axes import Axes

__all__ = ["in_upper_right"]


def in_upper_right(ax: Axes) -> bool:
    """Whether ``ax``'s legend reaches into the top tenth and the right tenth of the axes (the
    figure must have been drawn, so that the legend has its place)."""
    legend = ax.get_legend()
    assert legend is not None
    box, frame = legend.get_window_extent(), ax.get_window_extent()
    return bool(box.x1 > frame.x1 - 0.1 * frame.width and box.y1 > frame.y1 - 0.1 * frame.height)
