"""`photogram measure FIELD --guided PROJECT.prj`: guided measurement from
the bundle adjustment, after a first measurement.

The project reads the image points of a first ``photogram measure``
(ellipse centres: measured with ``--no-eccentricity``) and has
``[targets]`` (diameter, normal; the ``targets.toml`` that the first run
wrote). The project is adjusted, every target an image has no observation
of is predicted through the adjusted camera (lens distortion included),
measured by the edge fit started from the prediction, the project adjusted
again, until a round adds nothing
(:func:`photogram.measure.bundle_guided.guided_from_bundle`). The field
gives the images, polarity, channel, contrast and sigma floor.

Written into a NEW folder (default ``results-guided/`` beside the field
file, or ``--output``), never into the folder of the project's own
image points (an input):

* ``image_points.csv`` — every observation: the first measurement's
  rows, then the added ones (same columns and pixel convention);
* ``guided.csv`` — the added observations alone, with their round;
* ``summary.json`` (last) — per round the adjustment's sigma0, the added
  observations it removed (off the adjusted prediction), the targets
  predicted and added; per image the observations added.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from photogram.errors import InputError
from photogram.measure.bundle_guided import guided_from_bundle
from photogram.measure.field import read_field
from photogram.measure.pipeline import image_files, read_image
from photogram.project.atomic import atomic_write_text
from photogram.project.output_policy import claim_output

__all__ = ["guided_to_folder"]


def _check_project(project, prj: Path) -> Path:
    """The project's image points file, after the checks (module doc)."""
    if project.units.image != "px":
        raise InputError(f"image_unit is {project.units.image!r}; guided measurement works "
                         "in pixels", file=prj, hint='use image_unit = "px" (the unit '
                                                     "photogram measure writes)")
    targets = project.targets
    if targets is None or not targets.eccentricity:
        raise InputError("guided measurement needs [targets] with the eccentricity on "
                         "(the targets' diameter and normal)", file=prj,
                         hint="copy the [targets] of targets.toml that photogram measure "
                              "--no-eccentricity wrote into the project")
    src = project.sources.get("image_points")
    if src is None:
        raise InputError("the project has no image points table", file=prj,
                         hint="[observations] points = the image_points.csv of photogram "
                              "measure --no-eccentricity")
    summary = Path(src).parent / "summary.json"
    try:
        earlier = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        earlier = {}
    if earlier.get("eccentricity_correction") is True:
        raise InputError("these image points are corrected for eccentricity; with [targets] "
                         "the adjustment would correct them twice", file=src,
                         hint="measure again with --no-eccentricity (ellipse centres)")
    return Path(src)


def _rows(project, start: int = 0):
    obs, st, pts = project.image_points, project.stations.names, project.points.ids
    for i in range(start, len(obs.station)):
        yield st[obs.station[i]], pts[obs.point[i]], obs.xy[i, 0], obs.xy[i, 1], obs.sigma[i]


def guided_to_folder(field_path, project_path, output=None, *, images=None,
                     force: bool = False):
    """Run the guided measurement and write the output folder (module doc).

    Returns
    -------
    folder : Path
    report : photogram.measure.bundle_guided.BundleGuided
    n_before, n_after : int
        Observations of the first measurement and of the written table.
    """
    from photogram.project.reader import read_project
    from photogram.project.results_folder import output_lock, staged_results
    fld = read_field(field_path)
    prj = Path(project_path)
    if prj.is_dir():
        found = sorted(prj.glob("*.prj"))
        if len(found) != 1:
            raise InputError("give the .prj file", file=prj,
                             hint="the folder holds " + (f"{len(found)} .prj files" if found
                                                         else "no .prj file"))
        prj = found[0]
    project = read_project(prj)
    src_points = _check_project(project, prj)
    folder = Path(output) if output is not None else fld.path.parent / "results-guided"
    if folder.absolute().resolve() == src_points.absolute().resolve().parent:
        raise InputError("this folder holds the project's image points (an input of the "
                         "guided run)", file=folder,
                         hint="write a new folder: --output NEW_FOLDER (the default is "
                              "results-guided/ beside the field file)")
    src = Path(images) if images is not None else fld.images
    if src is None or not Path(src).is_dir():
        raise InputError("no folder of images", file=fld.path,
                         hint="give images = \"...\" in [field] or --images DIR")
    files = {p.stem: p for p in image_files(src)}
    inputs = [fld.path, prj] + list(project.sources.values()) + list(files.values())
    with output_lock(folder, command="measure --guided"):
        claim_output(folder, command="measure --guided", inputs=inputs, force=force)
        missing = [s for s in project.stations.names if s not in files]
        if missing:
            raise InputError(f"no image for station {missing[0]}", file=src,
                             hint="one image per station, named like the station (its stem)")
        t0 = time.perf_counter()
        grays = {s: read_image(files[s], fld.channel) for s in project.stations.names}
        n_before = len(project.image_points.station)
        out, report = guided_from_bundle(
            project, grays, polarity=fld.polarity, min_contrast=fld.min_contrast,
            min_diameter=fld.min_diameter, sigma_floor=fld.sigma_floor)
        seconds = time.perf_counter() - t0
        n_after = len(out.image_points.station)
        head = (f"# photogram measure --guided: {fld.name}, bundle of {prj.name}; px, x right, "
                f"y down, top-left corner of the image at (0, 0); ellipse centres")
        table = [head, "station,point,x,y,sigma"]
        table += [f"{s},{p},{x:.4f},{y:.4f},{g:.4f}" for s, p, x, y, g in _rows(out)]
        obs = out.image_points
        rounds = [report.round_of.get((int(obs.station[i]), int(obs.point[i])), 0)
                  for i in range(n_before, n_after)]
        added = [f"{s},{p},{x:.4f},{y:.4f},{g:.4f},{r}"
                 for (s, p, x, y, g), r in zip(_rows(out, n_before), rounds)]
        per_image: dict[str, int] = {s: 0 for s in project.stations.names}
        for line in added:
            per_image[line.split(",", 1)[0]] += 1
        summary = {"command": "measure --guided", "field": str(fld.path), "project": str(prj),
                   "first_measurement": str(src_points), "observations_before": n_before,
                   "observations": n_after, "added": n_after - n_before,
                   "rounds": [{"round": k + 1, "sigma0": round(float(s0), 4),
                               "removed": int(rm), "predicted": int(pr), "added": int(ad)}
                              for k, (s0, rm, pr, ad) in enumerate(zip(
                                  report.sigma0, report.removed, report.predicted,
                                  report.added))],
                   "added_per_image": per_image, "eccentricity_correction": False,
                   "seconds": round(seconds, 3)}
        with staged_results(folder, command="measure --guided", inputs=inputs) as stage:
            atomic_write_text(stage.path / "image_points.csv", "\n".join(table) + "\n")
            atomic_write_text(stage.path / "guided.csv",
                              "\n".join(["station,point,x,y,sigma,round"] + added) + "\n")
            atomic_write_text(stage.path / "summary.json", json.dumps(summary, indent=1) + "\n")
    return folder, report, n_before, n_after
