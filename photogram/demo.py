"""`photogram demo` (and `make demo`): the main job on the bundled example
projects, in the order a user runs it.

1. ``measure projects/lab/frame.toml``  the rendered photographs of the simulated lab
   frame measured (targets found, numbered from the ArUco markers), then checked
   against the typed observations ``lab_image_points.csv``; and
   ``calibrate projects/lab/lab.prj``   self-calibration of the lab frame from them
2. ``orient projects/field/field.prj``  the simulated arena, cameras from step 1
3. ``intersect projects/jumps/jumps.prj``  the simulated jump: jumper points,
   ski lines and the stick model, orientation covariance propagated; then
   ``track projects/jumps/track.prj``  the same jump from its rendered videos
   (markers and ski lines tracked) and ``intersect
   projects/jumps/jumps-video.prj``  the stick model from the tracked videos
4. ``montecarlo projects/jumps/montecarlo.prj --runs 200``  accuracy by
   simulation of orient + intersect, Monte Carlo versus propagated sigmas
5. ``mocap projects/ski-ptz/ski-ptz.prj``  markerless motion capture of a
   simulated giant-slalom run (6 pan-tilt cameras, known rotations), and
   ``mocap projects/ski-ptz/ski-ptz-estimate.prj`` the same with the rotations
   unknown (estimated from rotation differences measured on rendered images)
6. ``calibrate projects/camcal/camcal.prj``  DBAT's real CAMCAL network, and
   ``mocap projects/pose2sim-demo/demo.prj``  Pose2Sim's real demo, when
   ../shared/data is present beside the repository

Each step writes its results folder beside its project file.
"""

from __future__ import annotations

from pathlib import Path

from photogram.commands.bundle import announce, calibrate, orient
from photogram.commands.intersect import intersect_and_write
from photogram.errors import InputError
from photogram.project import read_project

ROOT = Path(__file__).resolve().parents[1]
PROJECTS = ROOT / "projects"


def _montecarlo(project, runs=200, force=False):
    """The demo's Monte Carlo: 200 runs (the project says 1000); ``force``
    computes every run again (when the demo replaces earlier results)."""
    from photogram.commands.montecarlo import montecarlo
    folder, summary = montecarlo(project, runs=runs, progress=False, force=force)
    ratios = {g: h["ratio"]["median"] for g, h in summary["headline"].items()}
    print(f"montecarlo: {summary['runs']} runs; sigma_mc / sigma_prop median per group: "
          + ", ".join(f"{g} {r:.2f}" for g, r in ratios.items()) + f"; results in {folder}")
    return folder, None


def _mocap(project):
    """photogram mocap (prints its own line)."""
    from photogram.commands.mocap import run as run_mocap
    run_mocap(project)
    return project.output_folder(), None


def _measure(path, report: bool = True):
    """photogram measure of a target field into its default folder (the demo
    replaces its own earlier measurement, and says so), then the check
    against the typed observations beside it; report.pdf and the drawn
    images unless ``report`` is false."""
    from photogram.commands.measure import measure_to_folder
    from photogram.measure.compare import compare_tables
    from photogram.project.output_policy import claim_output

    folder = path.parent / "results-measure"
    rel = path.relative_to(ROOT)
    if claim_output(folder, command="measure", force=True) != "new":
        print(f"measure {rel}: replacing the earlier results in {folder.relative_to(ROOT)}")
    folder, result = measure_to_folder(path, folder, force=True, report=report)
    per = [len([v for v in im.numbering.labels if v]) for im in result.images]
    print(f"measure {rel}: {len(result.table())} observations in {len(result.images)} images "
          f"({min(per)}-{max(per)} per image); results in {folder.relative_to(ROOT)}")
    typed = path.parent / "lab_image_points.csv"
    if typed.is_file():
        c = compare_tables(folder / "image_points.csv", typed, sigma_reference=0.33)
        print(f"measure {rel}: check against the typed {typed.name}: {c.line()}")
    return folder


def _track(path):
    """photogram track of the simulated jump's videos: rendered into
    ``video/`` first when they are missing (photogram.simulation.jump_video,
    a few seconds), then tracked into the project's output folder (the demo
    replaces its own earlier tracking)."""
    from photogram.commands.track import track_and_write
    from photogram.project.output_policy import claim_output, project_inputs

    videos = path.parent / "video"
    if not videos.is_dir():
        from photogram.simulation.jump_video import render_jump_videos, write_jump_videos
        write_jump_videos(render_jump_videos(), videos)
        print(f"track {path.relative_to(ROOT)}: rendered the simulated videos into "
              f"{videos.relative_to(ROOT)}")
    project = read_project(path)
    folder = project.output_folder()
    if claim_output(folder, command="track", force=True, inputs=project_inputs(project)) != "new":
        print(f"track {path.relative_to(ROOT)}: replacing the earlier results in "
              f"{folder.relative_to(ROOT)}")
    folder, result = track_and_write(project)
    s = result.summary
    truth = s.get("truth", {}).get("markers")
    check = (f"; against the truth: marker centres {truth['rms_px']:.3f} px RMS, "
             f"{truth['n_wrong']} wrong labels" if truth else "")
    print(f"track {path.relative_to(ROOT)}: {s['markers_found']} of {s['markers_expected']} "
          f"marker observations, {s['ski_lines_found']} of {s['ski_lines_expected']} ski lines"
          f"{check}; results in {folder.relative_to(ROOT)}")
    return folder


def steps():
    """(command, function, project path, needs) of the demo, in order."""
    return [("measure", _measure, PROJECTS / "lab" / "frame.toml", None),
            ("calibrate", calibrate, PROJECTS / "lab" / "lab.prj", None),
            ("orient", orient, PROJECTS / "field" / "field.prj", None),
            ("intersect", intersect_and_write, PROJECTS / "jumps" / "jumps.prj", None),
            ("track", _track, PROJECTS / "jumps" / "track.prj", None),
            ("intersect", intersect_and_write, PROJECTS / "jumps" / "jumps-video.prj", None),
            ("montecarlo", _montecarlo, PROJECTS / "jumps" / "montecarlo.prj", None),
            ("mocap", _mocap, PROJECTS / "ski-ptz" / "ski-ptz.prj", None),
            ("mocap", _mocap, PROJECTS / "ski-ptz" / "ski-ptz-estimate.prj", None),
            ("calibrate", calibrate, PROJECTS / "camcal" / "camcal.prj",
             ROOT.parent / "shared" / "data" / "dbat" / "camcal"),
            ("mocap", _mocap, PROJECTS / "pose2sim-demo" / "demo.prj",
             ROOT.parent / "shared" / "data" / "pose2sim-demo")]


def run(args=None):
    if not PROJECTS.is_dir():
        raise InputError("the example projects are not installed", file=PROJECTS,
                         hint="run the demo from a source checkout (make demo)")
    folders = []
    for command, function, path, needs in steps():
        if needs is not None and not Path(needs).is_dir():
            print(f"skipping {path.relative_to(ROOT)}: reference data {needs} not present")
            continue
        if not path.is_file():
            continue
        if command in ("measure", "track"):
            folders.append(function(path))
            continue
        project = read_project(path)
        from photogram.project.output_policy import claim_output, project_inputs
        mode = claim_output(project.output_folder(), command=command, force=True,
                            inputs=project_inputs(project), resumable=command == "montecarlo")
        if mode != "new":                 # the demo replaces its own results, and says so
            print(f"{command} {path.relative_to(ROOT)}: replacing the earlier results in "
                  f"{project.output_folder().relative_to(ROOT)}")
        if command == "montecarlo":      # replaced means computed again, never resumed
            folder, result = function(project, force=mode != "new")
        else:
            folder, result = function(project)
        if result is not None:
            announce(f"{command} {path.relative_to(ROOT)}", folder, result.summary, args)
        folders.append(folder)
    print("results: " + ", ".join(str(Path(f).resolve().relative_to(ROOT)) if
                                  Path(f).resolve().is_relative_to(ROOT) else str(f)
                                  for f in folders))
    return 0
