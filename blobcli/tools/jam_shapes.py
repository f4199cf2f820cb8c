"""`python -m blobcli.tools.jam_shapes`: φ_J against the blobs' preferred shape parameter 𝒜 = p₀² / (4π a), the
experiment of Boromand et al., PRL 121, 248003 (2018): deformable polygons jam denser the more slack their
perimeter, and tile the plane (confluence, φ_J → 1) at 𝒜* ≈ 1.16.

A blob's perimeter rests at its regular polygon's, p₀ = 2 n R sin(π/n), and its area is held at `pressure` × the
polygon's, so 𝒜 = 𝒜_n / pressure, 𝒜_n = n tan(π/n) / π the regular n-gon's (1.0032 at n = 32): each 𝒜 asked is
the scene with every blob's `pressure` = 𝒜_n / 𝒜. Each is jammed by `blobsim jam`'s protocol (tools/jam.py,
sim/jamming.py) from `--seeds` starts; `--count` copies per blob table (the box scaled to keep the start's φ).
Writes DIR/<scene>-shape-<𝒜>/ (each 𝒜's seeds and summary.json, as `blobsim jam` writes them), DIR/summary.json
(every 𝒜's scene text, pressure and the jam figures) and DIR/shapes.png, and prints a table.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path

DEFAULT_SHAPES = (1.0032, 1.05, 1.10, 1.13, 1.16, 1.20)
CONFLUENT = 1.16  # 𝒜*, Boromand et al. 2018


def regular_shape(n: int) -> float:
    """𝒜 of the regular n-gon: p² / (4π a) = n tan(π/n) / π."""
    return n * math.tan(math.pi / n) / math.pi


def shaped(text: str, shape: float, count: int | None) -> str:
    """The scene's TOML with every blob's pressure set for shape parameter `shape` (and `count` copies per table,
    the box's sides scaled by √(count / the scene's) so that the start's φ stays)."""
    from ..scene.schema import parse_scene
    scene = parse_scene(text, "<shapes>")
    pressures = [regular_shape(b.vertices) / shape for b in scene.blobs]
    out = re.sub(r"(?m)^pressure\s*=.*\n", "", text)
    tables = out.split("[[blob]]")
    for i, pressure in enumerate(pressures):
        tables[i + 1] = f"\npressure = {pressure!r}" + tables[i + 1]
        if count is not None:
            tables[i + 1] = re.sub(r"(?m)^count\s*=.*$", f"count = {count}", tables[i + 1])
    out = "[[blob]]".join(tables)
    if count is not None:
        scale = math.sqrt(count / scene.blobs[0].count)
        lx, ly = scene.settings.periodic
        out = re.sub(r"(?m)^periodic\s*=.*$", f"periodic = [{lx * scale!r}, {ly * scale!r}]", out)
    return out


def chart(rows: list[dict], png: Path) -> None:
    """φ_J (mean ± standard error over the seeds) against 𝒜, with 𝒜* and the discs' φ_J marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.2))
    done = [r for r in rows if r["phi_j"] is not None]
    ax.errorbar([r["shape"] for r in done], [r["phi_j"] for r in done],
                yerr=[r["phi_j_sem"] or 0.0 for r in done], fmt="o-", capsize=3, label="blobsim")
    for r in rows:
        if r["phi_j"] is None:
            ax.annotate("no jam below φ = 1", (r["shape"], 1.0), ha="center", va="top", fontsize=8)
    ax.axvline(CONFLUENT, color="0.5", ls="--", lw=0.8, label="A* ≈ 1.16, confluence (Boromand et al. 2018)")
    ax.axhline(0.842, color="0.5", ls=":", lw=0.8, label="φ_J = 0.842, discs (O'Hern et al. 2003)")
    ax.axhline(1.0, color="0.8", lw=0.8)
    ax.set_xlabel("shape parameter A = p₀² / (4π a)")
    ax.set_ylabel("φ_J")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    from ..io.outputs import replaced
    with replaced(png) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    from ..scene.schema import load_scene, parse_scene
    from . import jam
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="a jamming scene (scenes/jamming/bidisperse.toml)")
    ap.add_argument("--shapes", type=float, nargs="+", default=DEFAULT_SHAPES, help="the values of 𝒜")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--count", type=int, help="copies per blob table (default: the scene's)")
    ap.add_argument("-o", "--out", type=Path, default=Path("outputs/jam-shapes"))
    args = ap.parse_args(argv)
    base = load_scene(args.scene)
    text = Path(args.scene).read_text()
    rows = []
    for shape in args.shapes:
        scene = parse_scene(shaped(text, shape, args.count), f"{base.name}-shape-{shape:g}.toml")
        out = args.out / scene.name
        seeds, _ = jam.run_jam(scene, out, args.seeds, jam.DEFAULT_PRESSURE, announce=lambda line: None)
        figures = jam.summary(seeds)
        jam.write_json(figures, out / "summary.json")  # as `blobsim jam` writes it
        m = figures["mean"]
        rows.append({"shape": shape, "pressure": scene.blobs[0].pressure, "phi_j": m.get("phi_j"),
                     "phi_j_sem": m.get("phi_j_sem"), "z_j": m.get("z_j"), "jammed": len(figures["seeds"]),
                     "seeds": args.seeds, "failures": [r["status"] for r in seeds if r["status"] != "ok"],
                     "scene": scene.text})
        r = rows[-1]
        phi = "no seed jammed" if r["phi_j"] is None else f"phi_J = {r['phi_j']:.4f} ± {r['phi_j_sem'] or 0:.4f}"
        print(f"A = {shape:.4f} (pressure {r['pressure']:.4f}): {phi}, {r['jammed']}/{args.seeds} seeds", flush=True)
    jam.write_json({"rows": rows}, args.out / "summary.json")
    chart(rows, args.out / "shapes.png")
    print(f"summary {args.out / 'summary.json'}, chart {args.out / 'shapes.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
