"""`photogram simulate DESIGN`: a network design file becomes a complete
synthetic project with known truth (photogram.simulation.design_file)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from photogram.errors import InputError
from photogram.simulation.design_file import read_design, write_simulation


def simulate(design, output=None, *, seed=None, overwrite=False):
    """Read ``design``, simulate, write; returns ``(prj path, project, truth)``.

    The default output folder is ``results/<name>`` beside the design file
    (the name made a safe file name: :func:`photogram.project.safe_names.safe_name`).
    """
    des = read_design(design)
    if seed is not None:
        if seed < 0:
            raise InputError(f"--seed must be >= 0, not {seed}")
        des = dataclasses.replace(des, seed=int(seed))
    from photogram.project.safe_names import safe_name
    # the design's name is any text: as a folder name it stays inside results/
    folder = Path(output) if output else \
        Path(design).parent / "results" / safe_name(des.name, "design")
    return write_simulation(des, folder, overwrite=overwrite)


def run(args):
    if getattr(args, "design", None) is None:
        raise InputError("photogram simulate needs a design file",
                         hint="e.g. photogram simulate projects/designs/situation-b.toml")
    prj, project, truth = simulate(args.design, args.output, seed=args.seed,
                                   overwrite=getattr(args, "force", False))
    if not getattr(args, "quiet", False):
        n = len(project.image_points)
        extra = " and montecarlo.prj" if (prj.parent / "montecarlo.prj").is_file() else ""
        print(f"simulate: {len(project.stations)} stations, {len(project.points)} points, "
              f"{n} image points, {len(project.distances)} distances, "
              f"{len(project.verticals)} verticals; written {prj} with truth/{extra}")
    return 0
