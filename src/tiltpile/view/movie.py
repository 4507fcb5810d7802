"""A movie of a run: the pile drawn as in the paper's Fig. 3, one picture per stored frame.

Colour modes (``color``):

``clusters``  grains in critical clusters dark, failing grains (losing a contact by the next
              frame, the Fig. 3 convention: :mod:`tiltpile.view.fields` ``failing_next``) red
              when in a cluster and blue outside, other grains light grey, fixed grains grey;
              fully mobilized contacts as green lines
``force``     grains light grey; every active contact a black line of width ~ f_n / <f_n>
              (the force chains)
``speed``     grains coloured by |v| (log scale, viridis), with a colour bar

``forces=True`` adds the force chains to the ``clusters`` and ``speed`` pictures. The box is
drawn in its own frame (x along the floor), gravity as an arrow beside it at angle theta from
the -y axis; the title gives the run, frame, theta and the kinetic energy per mobile grain.

Output by file suffix: ``.mp4`` (H.264, through the ffmpeg binary that the ``imageio-ffmpeg``
wheel ships, or an ``ffmpeg`` on the PATH), ``.gif`` (Pillow; also the fallback when no ffmpeg
is found), ``.png`` (a still of one frame). One figure is drawn once; each frame only updates the
artists' offsets, colours and segments (no figure is re-created), so the cost per frame is one
Agg draw plus the encoder.
"""

from __future__ import annotations

import shutil
import time
import warnings
from pathlib import Path

import numpy as np

from tiltpile.store import open_run

from .fields import FrameFields, contact_segments, parse_frames
from .output import progress_frames, replaced_when_complete

COLORS_MODES = ("clusters", "force", "speed")
SUFFIXES = (".mp4", ".gif", ".png")


def ffmpeg_exe() -> str | None:
    """Path of an ffmpeg binary: the one shipped by ``imageio-ffmpeg``, else one on the PATH."""
    try:
        import imageio_ffmpeg
        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return shutil.which("ffmpeg")


def _palette():
    from tiltpile.figures import style
    c = style.COLORS
    return {"grain": c["grain"], "fixed": c["fixed"], "cluster": c["cluster"],
            "fail_in_cluster": c["fail_in_cluster"], "fail_outside": c["fail_outside"],
            "critical_contact": c["critical_contact"], "gravity": c["gravity"], "chain": "#000000"}


class PileArtist:
    """One matplotlib figure of the pile whose artists are updated frame after frame.

    ``draw(f)`` takes the dict of :meth:`FrameFields.fields`; ``fig`` is the figure. Sizes:
    ``width_px`` wide, height from the box's aspect (even pixel counts, as H.264 needs).
    """

    def __init__(self, box_length: float, height: float, n_grains: int, color: str = "clusters",
                 forces: bool = False, width_px: int = 1280, dpi: int = 100, label: str = ""):
        import matplotlib
        from matplotlib.collections import EllipseCollection, LineCollection
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D
        from matplotlib.patches import FancyArrowPatch

        if color not in COLORS_MODES:
            raise ValueError(f"color must be one of {', '.join(COLORS_MODES)}, got {color!r}")
        self.color, self.forces, self.label = color, forces or color == "force", label
        self.pal = _palette()
        L, H = float(box_length), float(height)
        self.L, self.H = L, H
        margin = max(0.06 * L, 0.3 * H)            # right of the box: the gravity arrow
        xr = (-0.02 * L, L + margin)
        yr = (-0.04 * H, H)
        top_in, bottom_in = 0.62, 0.08                # title and legend lines, bottom
        w_in = width_px / dpi
        ax_w = w_in * 0.98
        ax_h = ax_w * (yr[1] - yr[0]) / (xr[1] - xr[0])
        h_in = top_in + ax_h + bottom_in
        h_px = int(round(h_in * dpi / 2.0)) * 2
        width_px = int(round(width_px / 2.0)) * 2
        self.fig = fig = Figure(figsize=(width_px / dpi, h_px / dpi), dpi=dpi)
        h_in = h_px / dpi
        ax = self.ax = fig.add_axes((0.01, bottom_in / h_in, 0.98, ax_h / h_in))
        ax.set_xlim(*xr)
        ax.set_ylim(*yr)
        ax.set_aspect("equal", adjustable="box")
        ax.set_axis_off()
        ax.plot([0, 0, L, L], [H, 0, 0, H], color=self.pal["fixed"], lw=1.0, zorder=0)
        z = np.zeros(n_grains)
        self.grains = EllipseCollection(z, z, z, units="xy", offsets=np.zeros((n_grains, 2)),
                                        offset_transform=ax.transData, edgecolors="none",
                                        zorder=1)
        ax.add_collection(self.grains)
        self.chains = LineCollection([], colors=self.pal["chain"], zorder=2, capstyle="round")
        self.critical = LineCollection([], colors=self.pal["critical_contact"], linewidths=0.9,
                                       zorder=3, capstyle="round")
        ax.add_collection(self.chains)
        ax.add_collection(self.critical)
        self.cx, self.cy, self.glen = L + 0.5 * margin, 0.5 * H, 0.3 * H
        self.arrow = FancyArrowPatch((self.cx, self.cy), (self.cx, self.cy - self.glen),
                                     arrowstyle="-|>", mutation_scale=15, lw=1.5,
                                     color=self.pal["gravity"], zorder=4)
        ax.add_patch(self.arrow)
        ax.text(self.cx + 0.1 * H, self.cy + 0.3 * self.glen, "g",
                color=self.pal["gravity"], fontstyle="italic", fontsize=12)
        self.title = fig.text(0.01, 1.0 - 0.05 / h_in, "", ha="left", va="top", fontsize=10)
        self.cmap = matplotlib.colormaps["viridis"]
        self.norm = matplotlib.colors.LogNorm(1e-5, 1e-1, clip=True)
        handles, labels = [], []

        def dot(c):
            return Line2D([], [], ls="none", marker="o", ms=6, mfc=c, mec="none")
        if color == "clusters":
            handles = [dot(self.pal["cluster"]), dot(self.pal["fail_in_cluster"]),
                       dot(self.pal["fail_outside"]),
                       Line2D([], [], color=self.pal["critical_contact"], lw=1.5)]
            labels = ["in critical cluster", "failing, in cluster", "failing, outside",
                      "fully mobilized contact"]
        if self.forces:
            handles.append(Line2D([], [], color=self.pal["chain"], lw=1.5))
            labels.append(r"contact force (width $\propto f_n$)")
        if color == "speed":
            from matplotlib.cm import ScalarMappable
            cax = fig.add_axes((0.80, 1.0 - 0.40 / h_in, 0.17, 0.10 / h_in))
            cb = fig.colorbar(ScalarMappable(self.norm, self.cmap), cax=cax, orientation="horizontal")
            cb.ax.tick_params(labelsize=7)
            cb.set_label(r"$|v|$ [$\sqrt{g d}$]", fontsize=7, labelpad=1)
        if handles:
            fig.legend(handles, labels, loc="upper left", ncol=len(handles), fontsize=8,
                       frameon=False, bbox_to_anchor=(0.0, 1.0 - 0.26 / h_in),
                       handletextpad=0.3, columnspacing=1.2, borderaxespad=0.0)
        self._sized = None

    def draw(self, f: dict) -> None:
        """Update every artist to the frame ``f`` (:meth:`FrameFields.fields`)."""
        pal = self.pal
        fixed = f["fixed"]
        n = fixed.size
        g = self.grains
        if self._sized is not f["radius"]:           # the radii are the run's: set them once
            d = 2.0 * f["radius"]
            g.set_widths(d)
            g.set_heights(d)
            g.set_angles(np.zeros(n))
            self._sized = f["radius"]
        g.set_offsets(f["position"])
        if self.color == "speed":
            v = f["velocity"]
            colors = self.cmap(self.norm(np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-12)))
            colors[fixed] = (0.55, 0.55, 0.55, 1.0)
        else:
            cat = np.zeros(n, dtype=np.int8)
            if self.color == "clusters":
                inc = f["cluster"] >= 0
                fail = f["failing_next"]
                cat[inc] = 2
                cat[fail & inc] = 3
                cat[fail & ~inc] = 4
            cat[fixed] = 1
            table = np.array([_rgba(pal[k]) for k in ("grain", "fixed", "cluster",
                                                      "fail_in_cluster", "fail_outside")])
            colors = table[cat]
        g.set_facecolors(colors)
        pair, force = f["pair"], f["force"]
        seg = contact_segments(pair, f["position"], f["box_length"])
        if self.color == "clusters":
            self.critical.set_segments(seg[f["mobilized"]])
        if self.forces:
            act = f["active"]
            fn = force[act, 0]
            mean = fn.mean() if fn.size else 1.0
            self.chains.set_segments(seg[act])
            self.chains.set_linewidths(np.clip(0.6 * fn / mean, 0.05, 4.0))
        t = np.radians(f["theta_deg"])
        gx, gy = np.sin(t) * self.glen, -np.cos(t) * self.glen
        self.arrow.set_positions((self.cx - 0.5 * gx, self.cy - 0.5 * gy),
                                 (self.cx + 0.5 * gx, self.cy + 0.5 * gy))
        nm = int((~fixed).sum())
        ke = f["ke"] / nm if nm else float("nan")
        self.title.set_text(
            f"{self.label}frame {f['frame']}   " + rf"$\theta$ = {f['theta_deg']:.2f}$^\circ$   "
            + rf"$E_k$ / grain = {ke:.2e} $m g d$   t = {f['time']:.1f} $\sqrt{{d/g}}$")


def _rgba(c):
    from matplotlib.colors import to_rgba
    return to_rgba(c)


def _height(run, sel, radius) -> float:
    """Picture height: the highest grain top over the selected frames (at least the first
    frame's pile with a 10% margin)."""
    tops = [float(np.max(run.position(k)[:, 1] + radius)) for k in sel]
    return max(max(tops), 1.1 * tops[0])


# what the pictures assume whatever the caller's matplotlib style (a tight bounding box would
# change the frame size between frames, which the encoders refuse)
RC = {"savefig.bbox": "standard", "savefig.transparent": False, "savefig.facecolor": "white",
      "figure.facecolor": "white", "font.size": 10, "text.usetex": False}


def render(run_path, out, color: str = "clusters", frames: str | None = None, forces: bool = False,
           fps: int = 20, width_px: int = 1280, dpi: int = 100, progress: bool = True) -> dict:
    """Draw the selected frames of a run to ``out`` (.mp4, .gif, or .png for one frame).

    An .mp4 without any ffmpeg is written as a .gif beside it (a RuntimeWarning says so).
    Returns dict path, frames, width, height (pixels), bytes, seconds.
    """
    import matplotlib

    with matplotlib.rc_context(RC):
        return _render(run_path, out, color, frames, forces, fps, width_px, dpi, progress)


def _render(run_path, out, color, frames, forces, fps, width_px, dpi, progress) -> dict:
    from matplotlib import animation, rcParams

    t0 = time.perf_counter()
    out = Path(out)
    if out.suffix not in SUFFIXES:
        raise ValueError(f"{out}: the movie is written by suffix: {', '.join(SUFFIXES)}")
    if color not in COLORS_MODES:
        raise ValueError(f"--color must be one of {', '.join(COLORS_MODES)}, got {color!r}")
    with open_run(run_path) as run:
        sel = parse_frames(frames, run.n_frames)
        if out.suffix == ".png" and len(sel) != 1:
            raise ValueError(f"{out}: a still (.png) is one frame; select it with --frames K")
        ff = FrameFields(run)
        art = PileArtist(ff.box_length, _height(run, sel, ff.radius), ff.n, color, forces,
                         width_px, dpi, label=f"seed {run.seed}   ")
        fig = art.fig
        if out.suffix == ".png":
            art.draw(ff.fields(sel[0]))
            fig.savefig(out, dpi=dpi)
            w, h = fig.canvas.get_width_height()
            return {"path": str(out), "frames": 1, "width": w, "height": h,
                    "bytes": out.stat().st_size, "seconds": time.perf_counter() - t0}
        if out.suffix == ".mp4":
            exe = ffmpeg_exe()
            if exe is None:
                out = out.with_suffix(".gif")
                warnings.warn(f"no ffmpeg found (install imageio-ffmpeg); writing {out} instead",
                              RuntimeWarning, stacklevel=2)
        if out.suffix == ".mp4":
            rcParams["animation.ffmpeg_path"] = exe
            writer = animation.FFMpegWriter(fps=fps, codec="libx264", bitrate=-1,
                                            extra_args=["-pix_fmt", "yuv420p", "-crf", "23",
                                                        "-preset", "veryfast"])
        else:
            writer = animation.PillowWriter(fps=fps)
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        FigureCanvasAgg(fig)
        with replaced_when_complete(out, out.with_name(f".{out.stem}.tmp{out.suffix}")) as tmp, \
                writer.saving(fig, str(tmp), dpi):
            for k in progress_frames(sel, f"movie {out.name}", progress):
                art.draw(ff.fields(k))
                writer.grab_frame()
        w, h = fig.canvas.get_width_height()
    return {"path": str(out), "frames": len(sel), "width": w, "height": h,
            "bytes": out.stat().st_size, "seconds": time.perf_counter() - t0}
