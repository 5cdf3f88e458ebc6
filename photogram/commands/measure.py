"""`photogram measure FIELD`: automatic measurement of targets in photographs.

Reads the target-field description (:mod:`photogram.measure.field`),
measures every image of its folder (or ``--images DIR``) and writes into
the output folder (default ``results-measure/`` beside the field file, or
``--output``):

* ``image_points.csv`` — the observations in the project format
  (``station, point, x, y, sigma``; station = image file stem, px, corner
  convention), ready for ``[observations] points`` of a .prj;
* ``detections.csv`` — every accepted target with its quality measures
  (diameter, roundness, contrast, fit residual, sigma), its code and label,
  and every rejected blob with the reason;
* ``summary.json`` — counts per image and per target, timings, problems;
* ``images/NAME.png`` — each image downsampled with its detections, labels
  and rejections drawn, and ``report.pdf`` (a summary page and a page per
  image), unless ``--no-report`` (:mod:`photogram.measure.report`).

Each file is written atomically and ``summary.json`` last; an output
folder that holds an earlier run is not replaced without ``--force``.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.measure.field import read_field
from photogram.measure.pipeline import PIXEL_OFFSET, image_files, measure_images
from photogram.measure.report import draw_image, png_bytes, report_pdf
from photogram.project.atomic import atomic_write_bytes, atomic_write_text
from photogram.project.output_policy import claim_output

__all__ = ["run", "measure_to_folder", "observations_csv", "detections_csv", "targets_toml"]

log = logging.getLogger("photogram")


def observations_csv(measurement) -> str:
    """``image_points.csv`` text of a measurement."""
    lines = [f"# photogram measure: {measurement.field.name}; px, x right, y down, "
             f"top-left corner of the image at (0, 0)",
             "station,point,x,y,sigma"]
    for st, pt, x, y, s in measurement.table():
        lines.append(f"{st},{pt},{x:.4f},{y:.4f},{s:.4f}")
    return "\n".join(lines) + "\n"


def detections_csv(measurement) -> str:
    """``detections.csv``: accepted targets with quality measures, rejected blobs."""
    lines = ["image,status,label,code,x,y,diameter,roundness,contrast,residual,sigma,n_edge"]
    for im in measurement.images:
        d = im.detections
        for i in range(len(d)):
            code = im.code_label[i]
            status = "rejected:code" if code is None else \
                ("numbered" if im.numbering.labels[i] else "unnumbered")
            lines.append(
                f"{im.name},{status},{im.numbering.labels[i]},{code or ''},"
                f"{im.xy[i, 0]:.4f},{im.xy[i, 1]:.4f},{2 * d.axes[i, 0]:.2f},"
                f"{d.axes[i, 1] / d.axes[i, 0]:.3f},{d.contrast[i]:.1f},{d.residual[i]:.4f},"
                f"{im.sigma[i]:.4f},{d.n_edge[i]}")
        for (x, y), why in zip(d.rejected_xy, d.rejected_reason):
            lines.append(f"{im.name},rejected:{why},,,{x + PIXEL_OFFSET:.2f},"
                         f"{y + PIXEL_OFFSET:.2f},,,,,,")
    return "\n".join(lines) + "\n"


def targets_toml(fld) -> str | None:
    """``targets.toml``: the ``[targets]`` section of a project whose image
    points are this field's ellipse centres (``--no-eccentricity``), or
    None when the field has no diameter or no common normal."""
    if not fld.diameter > 0 or fld.shape != "circle":
        return None                                  # balls: no in-adjustment counterpart
    if fld.spatial:
        nv = fld.target_normal
        if nv is None or not len(nv) or not np.allclose(nv, nv[0], atol=1e-9):
            return None
        normal = nv[0]
    elif fld.grid_ids:
        normal = np.array([0.0, 0.0, 1.0])           # the grid lies in the plane Z = 0
    else:                                            # a plane of codes: its normal
        _, xyz = fld.coded3()
        if len(xyz) < 3:
            return None
        normal = np.linalg.svd(xyz - xyz.mean(axis=0))[2][2]
        normal = normal * (1 if normal[np.argmax(np.abs(normal))] > 0 else -1)
    n = ", ".join(f"{v:g}" for v in normal)
    return (f"# photogram measure: the targets of {fld.name} ({fld.path.name}).\n"
            f"# image_points.csv beside this file holds ellipse centres (--no-eccentricity):\n"
            f"# copy this section into the .prj that reads it, and the adjustment corrects\n"
            f"# their eccentricity (docs/measure.md, docs/project-files.md).\n"
            + (f"# The ArUco markers ({', '.join(sorted(fld.marker_xyz))}) are not circles: give\n"
               f"# them diameter = 0 in the points table (a diameter column; empty = this one).\n"
               if fld.marker_xyz else "")
            + f"[targets]\ndiameter = {fld.diameter:g}\nnormal = [{n}]\n")


def _summary(measurement, seconds: float, eccentricity: bool = True) -> dict:
    per_image = {im.name: im.counts() | {"seconds": round(im.seconds, 4)}
                 for im in measurement.images}
    per_target: dict[str, int] = {}
    for st, pt, *_ in measurement.table():
        per_target[pt] = per_target.get(pt, 0) + 1
    total = {}
    for c in per_image.values():
        for k, v in c.items():
            total[k] = total.get(k, 0) + v
    return {"command": "measure", "field": str(measurement.field.path),
            "name": measurement.field.name, "images": len(measurement.images),
            "observations": len(measurement.table()), "totals": total,
            "per_image": per_image, "per_target": dict(sorted(per_target.items())),
            "problems": measurement.problems(), "seconds": round(seconds, 3),
            "eccentricity_correction": bool(eccentricity),
            "pixel_convention": "corner: the image's top-left corner is (0, 0), the first "
                                "pixel's centre (0.5, 0.5)"}


def measure_to_folder(field_path, output=None, *, images=None, force: bool = False,
                      eccentricity_correction: bool = True, report: bool = True):
    """Measure and write the output folder (module doc); returns (folder, measurement)."""
    fld = read_field(field_path)
    folder = Path(output) if output is not None else fld.path.parent / "results-measure"
    src = Path(images) if images is not None else fld.images
    inputs = [fld.path] + (image_files(src) if src is not None and Path(src).is_dir() else [])
    from photogram.project.results_folder import output_lock, staged_results
    # one run per output folder (a lock), written whole or not at all (a
    # staging folder moved into place at the end), as every command
    with output_lock(folder, command="measure"):
        claim_output(folder, command="measure", inputs=inputs, force=force)
        t0 = time.perf_counter()
        drawings = {}

        def draw(res, gray):
            if report:
                drawings[res.name] = draw_image(gray, res)

        result = measure_images(fld, src, eccentricity_correction=eccentricity_correction,
                                progress=draw)
        seconds = time.perf_counter() - t0
        texts = {"image_points.csv": observations_csv(result),
                 "detections.csv": detections_csv(result)}
        summary = json.dumps(_summary(result, seconds, eccentricity_correction),
                             indent=1) + "\n"
        if not eccentricity_correction:
            snippet = targets_toml(fld)
            if snippet is not None:
                texts["targets.toml"] = snippet
        with staged_results(folder, command="measure", inputs=inputs) as stage:
            out = stage.path
            for name, text in texts.items():
                atomic_write_text(out / name, text)
            if report:
                (out / "images").mkdir(exist_ok=True)
                for name, img in drawings.items():
                    atomic_write_bytes(out / "images" / f"{name}.png", png_bytes(img))
                atomic_write_bytes(out / "report.pdf", report_pdf(result, drawings))
            atomic_write_text(out / "summary.json", summary)
    return folder, result


def run(args) -> int:
    """Command-line entry (``photogram measure FIELD [--images DIR] [--output DIR]
    [--guided PROJECT]``)."""
    if getattr(args, "field", None) is None:
        raise InputError("photogram measure: which target field?",
                         hint="give its description, e.g. photogram measure "
                              "projects/camcal/sheet.toml")
    if getattr(args, "guided", None) is not None:
        from photogram.commands.measure_guided import guided_to_folder
        folder, rep, n0, n1 = guided_to_folder(args.field, args.guided, args.output,
                                               images=args.images, force=args.force)
        if not getattr(args, "quiet", False):
            print(f"measure --guided: {n0} -> {n1} observations in {rep.rounds} rounds "
                  f"(added {', '.join(str(a) for a in rep.added)}) "
                  f"-> {folder / 'image_points.csv'}")
        return 0
    folder, result = measure_to_folder(args.field, args.output, images=args.images,
                                       force=args.force,
                                       eccentricity_correction=not args.no_eccentricity,
                                       report=not args.no_report)
    for p in result.problems():
        log.warning("%s", p)
    n = len(result.table())
    per = [len([v for v in im.numbering.labels if v]) for im in result.images]
    if not getattr(args, "quiet", False):
        print(f"measure: {n} observations in {len(result.images)} images "
              f"({min(per)}-{max(per)} per image) -> {folder / 'image_points.csv'}")
    return 0
