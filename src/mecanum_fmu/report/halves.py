"""Draw a two-column dashboard in two processes at once.

Rendering the text of six panels is most of what the plots cost once the results are in. The
plot worker (a process of its own, one thread) forks: the child draws the right column, hands
its half of the pixels back through a pipe and then writes its panels' PNGs, while this process
draws the left column (and the title, which both draw alike), writes its panels' PNGs on a
thread and, once the right half is in, dashboard.png. PNG encoding releases the GIL. A panel
never paints into the other column (the cut of panel PNGs relies on that too), so the two
halves make exactly the picture one draw would: the tests compare the bytes.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np
from matplotlib.figure import Figure

Save = Callable[[np.ndarray, list[int]], None]     # (RGBA pixels, indices of axes to write)


def draw_in_halves(fig: Figure, save: Save, save_whole: Callable[[np.ndarray], None]) -> None:
    """Draw `fig`; `save` is called for every axes (by the process that drew it), `save_whole`
    with the whole picture. Without fork (or without a right column): one draw here."""
    right = [i for i, ax in enumerate(fig.axes) if ax.get_position().x0 >= 0.5]
    left = [i for i in range(len(fig.axes)) if i not in right]
    if not right or not hasattr(os, "fork"):
        pixels = _draw_showing(fig, left + right)
        save(pixels, left + right)
        save_whole(pixels)
        return
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:                          # the child: never returns
        os.close(read_end)
        _child(fig, right, save, write_end)
    os.close(write_end)
    try:
        with ThreadPoolExecutor(1) as pool:
            pixels = _draw_showing(fig, left).copy()
            panels = pool.submit(save, pixels, left)
            half = _read_all(read_end)
            save_whole(_joined(pixels, half))
            panels.result()
    finally:
        os.close(read_end)
        status = os.waitpid(pid, 0)[1]
        for ax in fig.axes:
            ax.set_visible(True)
    if status != 0:
        raise RuntimeError(f"the process drawing the right column failed (status {status})")


def _joined(pixels: np.ndarray, half: bytes) -> np.ndarray:
    """The left picture with the right half's pixels put in (the column boundary of
    plots.panel_boxes)."""
    width = int(pixels.shape[1] / 2)
    if len(half) != pixels.shape[0] * (pixels.shape[1] - width) * 4:
        raise RuntimeError("the process drawing the right column sent no picture")
    joined = pixels.copy()
    joined[:, width:] = np.frombuffer(half, dtype=np.uint8).reshape(pixels.shape[0], -1, 4)
    return joined


def _draw_showing(fig: Figure, shown: list[int]) -> np.ndarray:
    for i, ax in enumerate(fig.axes):
        ax.set_visible(i in shown)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())


def _child(fig: Figure, right: list[int], save: Save, fd: int) -> None:
    code = 1
    try:
        pixels = _draw_showing(fig, right)
        view = memoryview(np.ascontiguousarray(pixels[:, int(pixels.shape[1] / 2):]).tobytes())
        while view:
            view = view[os.write(fd, view):]
        os.close(fd)
        save(pixels, right)
        code = 0
    finally:
        os._exit(code)      # no clean-up of the parent's objects, nothing on its stdout


def _read_all(fd: int) -> bytes:
    chunks = []
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
    return b"".join(chunks)
