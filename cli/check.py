"""``photogram check PROJECT``: validate a project and print a summary."""

from __future__ import annotations

import argparse
from pathlib import Path

from photogram.project import Project, write_project
from photogram.project.results import project_counts


def _cameras(project: Project) -> str:
    parts = []
    for name, cam in project.cameras.items():
        free = sum(p.free for p in cam.parameters.values())
        weighted = sum(p.free and p.sigma is not None for p in cam.parameters.values())
        text = f"{name} ({cam.model}, {free} free" + (f", {weighted} weighted" if weighted else "")
        text += _sharing(cam)
        parts.append(text + (f", from {cam.source})" if cam.source else ")"))
    shown = ", ".join(parts[:4])
    return shown + (f", ... {len(parts) - 4} more" if len(parts) > 4 else "")


def _sharing(cam) -> str:
    """``", per station x0 y0, fy = fx, c in group lens"`` (docs/project-files.md,
    "Parameter sharing"), or ``""``."""
    parts = []
    if cam.per_station:
        parts.append("per station " + " ".join(cam.per_station))
    parts += [f"{p} = {q}" for p, q in cam.ties.items()]
    parts += [f"{p} in group {g}" for p, g in cam.shared.items()]
    return "".join(", " + x for x in parts)


def summary_lines(project: Project) -> list[str]:
    """The one-screen summary of a validated project."""
    n = project_counts(project)
    kinds = n["points_by_kind"]
    u = project.units
    adj = project.adjustment
    rows = [
        ("project", f"{project.name}  (lengths {u.length}, angles {u.angle}, image {u.image}; "
                    f"omega-phi-kappa {project.rotation_direction})"),
        ("cameras", f"{n['cameras']}: {_cameras(project)}"),
        ("stations", str(n["stations"])),
        ("points", f"{n['points']}: {kinds['control']} control, {kinds['check']} check, "
                   f"{kinds['tie']} tie"),
        ("observations", f"{n['image_points']} image points, {n['image_lines']} image-line points"),
        ("rays/point", f"min {n['rays_min']}, max {n['rays_max']}"),
        ("constraints", f"{n['distances']} distance, {n['verticals']} vertical"),
        ("adjustment", f"datum {adj.datum}, sigma_image {adj.sigma_image:g} {u.image}, "
                       f"max_iterations {adj.max_iterations}"),
        ("output", str(project.output_folder())),
    ]
    t = getattr(project, "track", None)
    if t is not None:      # a tracking project: its videos instead of observations
        offsets = "estimated" if t.offsets is None else \
            ", ".join(f"{k} {v:+d}" for k, v in t.offsets.items()) or "none"
        rows[4:6] = [("track", f"{len(t.videos)} videos ({', '.join(t.videos)}), markers "
                               f"{' '.join(t.markers)}, skis {' '.join(t.skis)}, "
                               f"offsets {offsets}")]
        rows = [r for r in rows if r[0] not in ("points", "constraints", "adjustment")]
    lines = [f"{project.path}: ok"] + [f"  {k:<13} {v}" for k, v in rows]
    lines += [f"warning: {w}" for w in project.warnings] or ["warnings: none"]
    return lines


def run(project: Project, args: argparse.Namespace) -> int:
    """Print the summary; with ``--output`` also write a normalised copy."""
    if not args.quiet:
        print("\n".join(summary_lines(project)))
    if args.output is not None:
        folder = Path(args.output)
        folder.mkdir(parents=True, exist_ok=True)
        written = write_project(project, folder / f"{project.path.stem}.prj",
                                overwrite=args.force)
        if not args.quiet:
            print(f"written: {written}")
    return 0
