"""The thesis' Example 2.2 (Choi 2008, §2.5.4): two elliptic disks under degree-4 rational motions that touch
at t = 1/2 (with the corrected x-translation of M_A), drawn at t = 0, 0.25, 0.5 and 0.75.

    python examples/plot_example_2_2.py [out.png]    (default: docs/images/example_2_2.png)
"""
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # headless
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mjccd.geoms.planar import Ellipse, PlanarMotion, ellipse_first_contact  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
C, S, W = [4, -16, 0, 32, -16], [0, 16, -48, 32], [4, -16, 32, -32, 16]  # -S is [0, -16, 48, -32]
NEG_S = [-x for x in S]
MA = PlanarMotion([[C, NEG_S, [40, -160, 240, -160]], [S, C, [80, -400, 880, -960, 480]], [0, 0, W]])
MB = PlanarMotion([[C, S, [-40, 160, -240, 160]], [NEG_S, C, [-80, 400, -880, 960, -480]], [0, 0, W]])
DISK = Ellipse(5, 10)


def outline(motion, t, n=200):
    th = np.linspace(0.0, 2.0 * np.pi, n)
    pts = motion.at(t) @ np.stack([DISK.a * np.cos(th), DISK.b * np.sin(th), np.ones(n)])
    return pts[0] / pts[2], pts[1] / pts[2]


def main(out=ROOT / "docs" / "images" / "example_2_2.png"):
    contact = ellipse_first_contact(DISK, MA, DISK, MB)
    fig, axes = plt.subplots(1, 4, figsize=(12, 4), sharey=True)
    for ax, t in zip(axes, (0.0, 0.25, 0.5, 0.75)):
        for motion, colour, name in ((MA, "tab:blue", "A"), (MB, "tab:orange", "B")):
            ax.fill(*outline(motion, t), color=colour, alpha=0.35, label=name)
            ax.plot(*outline(motion, t), color=colour)
        if abs(t - contact.time) < 1e-9:
            ax.plot(*contact.point, "k*", markersize=12, label="contact")
        ax.set_title(f"t = {t:g}")
        ax.set_aspect("equal")
        ax.set_xlim(-25, 25)
        ax.set_ylim(-30, 30)
    axes[2].legend(loc="lower right", fontsize=8)
    x, y = np.round(contact.point, 9) + 0.0
    fig.suptitle(f"Example 2.2: first contact at t = {contact.time:.12g}, point ({x:g}, {y:g}), {contact.certainty}")
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print(f"wrote {out}: first contact at t = {contact.time!r}, point {contact.point.tolist()}")


if __name__ == "__main__":
    main(*sys.argv[1:])
