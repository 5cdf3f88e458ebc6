"""Network design files (TOML) for ``photogram simulate``: a planned network
becomes a complete synthetic project with known truth.

A design either names one of the paper's networks::

    [design]
    builtin = "lab"            # lab_design (Fig. 5) | "arena" (field_design, Fig. 7)
    seed = 20250101
    alternative = 1            # arena only: 1 or 2 (with the helmet)

or describes the network itself::

    [design]
    name = "situation-b"
    seed = 20250104
    length_unit = "dm"
    angle_unit = "gon"
    sigma_image = 0.33         # px, N(0, sigma) on every image coordinate (rounded to 0.01 px)
    margin = 4                 # px: points closer to the border are not measured
    datum = "weighted"         # [adjustment] datum of the project
    approximation = 1.0        # sigma (length unit) of the given point and station
                               # approximations; angles get approximation / 100 rad

    [cameras.K1]               # the TRUE interior orientation (brown, px)
    image_size = [640, 480]
    c = 1420.0
    x0 = 323.4
    K1 = -5.2e-8
    free = ["c", "K1"]         # unknown in the adjustment (the others fixed ...)
    given = { c = 1400.0, x0 = 320.0, y0 = 240.0, K1 = 0.0, K2 = 0.0 }  # ... at these values

    [[stations]]
    name = "S1"
    camera = "K1"
    position = [300.0, 500.0, -150.0]
    look_at = [499.0, -10.0, -286.0]
    roll = -3.0                # angle unit, about the viewing axis
    sigma_position = 10.0      # optional prior (appendix D.2), length unit

    [[points]]                 # reference (sigma: surveyed, kind control) or tie points
    id = "M1"
    xyz = [415.0, -60.0, -260.0]
    sigma = 0.12

    [[rods]]                   # a vertical rod with two targets, id + "a" (foot), id + "b"
    id = "R1"
    foot = [430.0, -40.0, -270.0]
    length = 20.0              # length unit; observed as a distance
    sigma_length = 0.01
    sigma_vertical = 0.01      # slope ratio (1:100), eq. (3)

    [jumper]                   # points of the simulated jump as tie points
    exposures = 24             # photogram.simulation.jump.jump_truth; 2 .. 1000
    points = ["P1"]            # P1 helmet, P2 hip, P3 / P4 bindings
    every = 2                  # every 2nd exposure

    [montecarlo]               # optional: written as montecarlo.prj beside the project
    runs = 500                 # 1 .. 100000 (workers 1 .. 256)
    perturb = ["image", "constraints"]

:func:`read_design` validates the file (one InputError with file and line
per mistake); :func:`simulate_design` returns ``(project, truth)``;
:func:`write_simulation` writes the .prj with its CSV tables, ``truth/``
and (if asked) ``montecarlo.prj``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model, matrix_to_opk, opk_to_matrix
from photogram.project.model import (
    ANGLE_UNITS, DATUMS, LENGTH_UNITS, PERTURBATIONS, AdjustmentSettings, Camera,
    DistanceConstraint, ImagePoints, OutputSettings, Parameter, Points, Project, Stations,
    Units, VerticalConstraint)
from photogram.project.reader import MAX_RUNS, MAX_WORKERS
from photogram.project.toml_source import Section, TomlSource
from photogram.simulation.network import look_at, observe, roll

__all__ = ["Design", "read_design", "simulate_design", "write_simulation", "BUILTINS"]

BUILTINS = ("lab", "arena")
#: most exposures of a simulated jump (the design is refused above it)
MAX_EXPOSURES = 1000
PARAMS = camera_model("brown").parameter_names
_ANGLE = {"rad": 1.0, "deg": np.pi / 180.0, "gon": np.pi / 200.0}


@dataclass
class Design:
    """A validated design file."""

    path: Path
    name: str
    seed: int
    builtin: str | None = None
    alternative: int = 1
    length_unit: str = "m"
    angle_unit: str = "gon"
    sigma_image: float = 0.33
    margin: float = 4.0
    datum: str = "weighted"
    approximation: float = 0.0
    cameras: dict = field(default_factory=dict)     # name -> (truth, free, given, size)
    stations: list = field(default_factory=list)    # dicts
    points: list = field(default_factory=list)      # (id, xyz, sigma or None)
    rods: list = field(default_factory=list)        # dicts
    jumper: dict | None = None
    montecarlo: dict | None = None


def _vector(sec: Section, key: str, n=3):
    value = sec.data.get(key)
    if not isinstance(value, list) or len(value) != n or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise sec.error(key if key in sec.data else None,
                        f"{key} in {sec.label} must be an array of {n} numbers",
                        hint=f"e.g. {key} = [1.0, 2.0, 3.0]")
    return np.array(value, dtype=float)


def read_design(path) -> Design:
    """Read and validate a design file."""
    path = Path(path)
    if not path.is_file():
        raise InputError("design file not found", file=path,
                         hint="give the path of a .toml design (projects/designs/)")
    src = TomlSource.load(path, what="design file")
    root = src.root()
    root.check_keys(("design", "cameras", "stations", "points", "rods", "jumper", "montecarlo"),
                    noun="section")
    d = root.table("design")
    builtin = d.string("builtin", None, choices=BUILTINS)
    if builtin:
        d.check_keys(("builtin", "seed", "alternative", "name"))
        extra = [k for k in root.data if k not in ("design", "montecarlo")]
        if extra:
            raise root.error(extra[0], f"[{extra[0]}] in a builtin design",
                             hint=f"builtin = \"{builtin}\" defines the whole network")
        return Design(path, d.ident("name", builtin), d.integer("seed", 0, minimum=0),
                      builtin=builtin, alternative=d.integer("alternative", 1, minimum=1),
                      montecarlo=_montecarlo(root))
    d.check_keys(("name", "seed", "length_unit", "angle_unit", "sigma_image", "margin", "datum",
                  "approximation"))
    des = Design(path, d.ident("name", path.stem), d.integer("seed", 0, minimum=0),
                 length_unit=d.string("length_unit", "m", choices=tuple(LENGTH_UNITS)),
                 angle_unit=d.string("angle_unit", "gon", choices=ANGLE_UNITS),
                 sigma_image=d.number("sigma_image", 0.33, positive=True),
                 margin=d.number("margin", 4.0, nonnegative=True),
                 datum=d.string("datum", "weighted", choices=DATUMS),
                 approximation=d.number("approximation", 0.0, nonnegative=True))
    cams = root.table("cameras")
    for name in cams.data:
        c = cams.table(name)
        c.check_keys(("image_size",) + PARAMS + ("free", "given"), required=("c", "image_size"))
        size = c.numbers("image_size", 2, integer=True)
        truth = {p: c.number(p, 0.0) for p in PARAMS}
        if "x0" not in c.data:
            truth["x0"] = size[0] / 2.0
        if "y0" not in c.data:
            truth["y0"] = size[1] / 2.0
        free = c.ids("free", [])
        for p in free:
            if p not in PARAMS:
                raise c.error("free", f"unknown parameter '{p}' in free of {c.label}",
                              hint="brown: " + ", ".join(PARAMS))
        given = dict(truth)
        if "given" in c.data:
            g = c.table("given")
            g.check_keys(PARAMS)
            given.update({p: g.number(p) for p in g.data})
        des.cameras[name] = (truth, free, given, size)
    for s in root.table_array("stations"):
        s.check_keys(("name", "camera", "position", "look_at", "roll", "sigma_position"),
                     required=("name", "camera", "position", "look_at"))
        cam = s.ident("camera")
        if cam not in des.cameras:
            raise s.error("camera", f"unknown camera '{cam}' in {s.label}",
                          hint="define it as [cameras." + cam + "]")
        des.stations.append({"name": s.ident("name"), "camera": cam,
                             "position": _vector(s, "position"), "look_at": _vector(s, "look_at"),
                             "roll": s.number("roll", 0.0) * _ANGLE[des.angle_unit],
                             "sigma_position": s.number("sigma_position", None, positive=True)})
    if not des.stations:
        raise root.error(None, "the design has no [[stations]]", hint="add at least two")
    for p in root.table_array("points"):
        p.check_keys(("id", "xyz", "sigma"), required=("id", "xyz"))
        des.points.append((p.ident("id"), _vector(p, "xyz"), p.number("sigma", None,
                                                                      positive=True)))
    for r in root.table_array("rods"):
        r.check_keys(("id", "foot", "length", "sigma_length", "sigma_vertical"),
                     required=("id", "foot", "length"))
        des.rods.append({"id": r.ident("id"), "foot": _vector(r, "foot"),
                         "length": r.number("length", positive=True),
                         "sigma_length": r.number("sigma_length", 0.01, positive=True),
                         "sigma_vertical": r.number("sigma_vertical", 0.01, positive=True)})
    j = root.table("jumper", required=False)
    if j is not None:
        j.check_keys(("exposures", "points", "every"))
        pts = j.ids("points", ["P1"])
        bad = [q for q in pts if q not in ("P1", "P2", "P3", "P4")]
        if bad:
            raise j.error("points", f"unknown jumper point '{bad[0]}'",
                          hint="P1 helmet, P2 hip, P3 right and P4 left binding")
        _at_most(j, "exposures", MAX_EXPOSURES, "a jump at 30 fps has about 100")
        des.jumper = {"exposures": j.integer("exposures", 24, minimum=2), "points": pts,
                      "every": j.integer("every", 1, minimum=1)}
    ids = [p[0] for p in des.points] + [f"{r['id']}{e}" for r in des.rods for e in "ab"]
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        raise root.error("points", f"point id(s) {', '.join(sorted(dup))} used twice")
    des.montecarlo = _montecarlo(root)
    return des


def _at_most(sec: Section, key: str, top: int, hint: str):
    """Refuse an integer above ``top`` before anything is allocated."""
    value = sec.data.get(key)
    if isinstance(value, int) and not isinstance(value, bool) and value > top:
        raise sec.error(key, f"{key} in {sec.label} must be at most {top}, not {value}",
                        hint=hint)


def _montecarlo(root):
    m = root.table("montecarlo", required=False)
    if m is None:
        return None
    m.check_keys(("runs", "seed", "perturb", "workers", "chunk"))
    _at_most(m, "runs", MAX_RUNS, "1000 runs give sigmas to 2 %")
    _at_most(m, "workers", MAX_WORKERS, "one worker per CPU core")
    perturb = m.ids("perturb", ["image", "reference", "constraints"])
    for p in perturb:
        if p not in PERTURBATIONS:
            raise m.error("perturb", f"unknown perturbation '{p}'",
                          hint="use any of " + ", ".join(PERTURBATIONS))
    return {"runs": m.integer("runs", 500, minimum=1), "seed": m.integer("seed", 1, minimum=0),
            "perturb": perturb, "workers": m.integer("workers", 1, minimum=1),
            "chunk": m.integer("chunk", 50, minimum=1)}


# ---------------------------------------------------------------------------
# simulation

def _rng(seed, stream):
    return np.random.default_rng([int(seed), stream])


def simulate_design(des: Design):
    """``(project, truth)`` of a design (a pure function of the design)."""
    if des.builtin == "lab":
        from photogram.simulation.designs import LAB_SEED, lab_design
        project, truth = lab_design(des.seed or LAB_SEED)
    elif des.builtin == "arena":
        from photogram.simulation.designs import FIELD_SEED, field_design
        if des.alternative not in (1, 2):
            raise InputError("alternative must be 1 or 2", file=des.path)
        project, truth = field_design(des.seed or FIELD_SEED, des.alternative)
    else:
        return _simulate_network(des)
    project.name = des.name
    project.output = OutputSettings(folder="results")
    return project, truth


def _simulate_network(des: Design):
    names = list(des.cameras)
    io_true = np.array([[des.cameras[n][0][p] for p in PARAMS] for n in names])
    sizes = {des.cameras[n][3] for n in names}
    if len(sizes) != 1:
        raise InputError("all cameras of a design need the same image_size", file=des.path)
    size = sizes.pop()
    st = des.stations
    cam_index = np.array([names.index(s["camera"]) for s in st])
    X0 = np.array([s["position"] for s in st])
    R = roll(look_at(X0, np.array([s["look_at"] for s in st])), np.array([s["roll"] for s in st]))
    ids = [p[0] for p in des.points]
    xyz = [p[1] for p in des.points]
    sig = [p[2] for p in des.points]
    distances, verticals = [], []
    for r in des.rods:
        a, b = f"{r['id']}a", f"{r['id']}b"
        ids += [a, b]
        xyz += [r["foot"], r["foot"] + np.array([0.0, 0.0, r["length"]])]
        sig += [None, None]
        distances.append(DistanceConstraint(a, b, r["length"], r["sigma_length"]))
        verticals.append(VerticalConstraint(b, a, r["sigma_vertical"]))
    if des.jumper:
        from photogram.simulation.jump import jump_truth
        jt = jump_truth(des.jumper["exposures"])
        k = {"P1": 0, "P2": 1, "P3": 2, "P4": 3}
        for e in range(0, des.jumper["exposures"], des.jumper["every"]):
            for q in des.jumper["points"]:
                ids.append(f"{q}@{e + 1:03d}")
                xyz.append(jt["P"][e, k[q]])
                sig.append(None)
    xyz = np.array(xyz, dtype=float)
    net = observe("brown", io_true, cam_index, R, X0, xyz, size, sigma=0.0, margin=des.margin)
    rays = np.bincount(net.point, minlength=len(ids))
    if np.any(rays < 2):
        bad = [ids[i] for i in np.flatnonzero(rays < 2)]
        raise InputError(f"design: point(s) {', '.join(bad[:5])} are seen in fewer than 2 images",
                         file=des.path, hint="move them or the cameras")
    xy = np.round(net.xy_true + _rng(des.seed, 1).normal(0.0, des.sigma_image,
                                                        net.xy_true.shape), 2)
    kind = np.array(["control" if s is not None else "tie" for s in sig], dtype=object)
    psig = np.array([[s] * 3 if s is not None else [np.nan] * 3 for s in sig], dtype=float)
    given = xyz.copy()
    ctrl = kind == "control"
    given[ctrl] = np.round(xyz[ctrl] + _rng(des.seed, 2).normal(0.0, 1.0, (ctrl.sum(), 3))
                           * psig[ctrl], 3)
    a = des.approximation
    rng = _rng(des.seed, 3)
    given[~ctrl] = np.round(xyz[~ctrl] + rng.normal(0.0, a, ((~ctrl).sum(), 3)), 3)
    angles = matrix_to_opk(R)
    ap_X0 = np.round(X0 + rng.normal(0.0, a, X0.shape), 3)
    ap_ang = matrix_to_opk(opk_to_matrix(angles) if a == 0 else
                           _small(rng.normal(0.0, a / 100.0, angles.shape)) @ R)
    sp = np.array([[s["sigma_position"]] * 3 if s["sigma_position"] else [np.nan] * 3
                   for s in st], dtype=float)
    if np.isfinite(sp).any():
        # the prior values are the truth plus noise of their sigma
        prior = np.isfinite(sp[:, 0])
        ap_X0[prior] = np.round(X0[prior] + _rng(des.seed, 4).normal(0.0, 1.0, (prior.sum(), 3))
                                * sp[prior], 3)
    cams = {}
    for n in names:
        _, free, gv, sz = des.cameras[n]
        cams[n] = Camera(n, "brown", {p: Parameter(float(gv[p]), p in free) for p in PARAMS},
                         image_size=tuple(sz))
    project = Project(
        name=des.name, units=Units(length=des.length_unit, angle=des.angle_unit, image="px"),
        cameras=cams,
        stations=Stations(names=[s["name"] for s in st], camera=[s["camera"] for s in st],
                          position=ap_X0, angles=ap_ang, position_sigma=sp,
                          angle_sigma=np.full((len(st), 3), np.nan)),
        points=Points(ids=ids, kind=kind, xyz=given, sigma=psig),
        image_points=ImagePoints(station=net.station, point=net.point, xy=xy,
                                 sigma=np.full(len(xy), np.nan)),
        distances=distances, verticals=verticals,
        adjustment=AdjustmentSettings(datum=des.datum, sigma_image=des.sigma_image),
        output=OutputSettings(folder="results"))
    truth = {"seed": des.seed, "sigma_image": des.sigma_image,
             "points": {"ids": ids, "xyz": xyz},
             "stations": {"names": [s["name"] for s in st], "camera": [s["camera"] for s in st],
                          "X0": X0, "angles": angles, "R": R},
             "cameras": {n: dict(zip(PARAMS, io_true[i])) for i, n in enumerate(names)},
             "distances": [{"from": d.point_a, "to": d.point_b, "true": d.value,
                            "value": d.value, "sigma": d.sigma} for d in distances],
             "xy_true": net.xy_true}
    return project, truth


def _small(rv):
    from photogram.geometry import small_rotation
    return small_rotation(rv)


# ---------------------------------------------------------------------------
# files

def _truth_tables(project, truth):
    from photogram.project.tables import format_angle, format_table
    unit_l, unit_a = project.units.length, project.units.angle
    st = truth["stations"]
    stations = {"station": st["names"], "camera": st["camera"]}
    for j, c in enumerate(("X0", "Y0", "Z0")):
        stations[c] = st["X0"][:, j]
    for j, c in enumerate(("omega", "phi", "kappa")):
        stations[c] = [format_angle(a, unit_a) for a in st["angles"][:, j]]
    pts = truth["points"]
    points = {"id": list(pts["ids"]), "kind": [str(k) for k in project.points.kind]}
    for j, c in enumerate("XYZ"):
        points[c] = pts["xyz"][:, j]
    cameras = {"camera": list(truth["cameras"])}
    for p in PARAMS:
        cameras[p] = [float(truth["cameras"][c][p]) for c in truth["cameras"]]
    xy = np.round(truth["xy_true"], 6)
    obs = project.image_points
    image = {"station": [st["names"][i] for i in obs.station],
             "point": [pts["ids"][i] for i in obs.point], "x": xy[:, 0], "y": xy[:, 1]}
    head = f"SIMULATED data (photogram simulate, seed {truth['seed']}): "
    out = {"cameras.csv": format_table(cameras, comment=head + "true interior orientation (px)"),
           "stations.csv": format_table(stations, comment=head + f"true stations ({unit_l}; "
                                        f"{unit_a}, world_to_camera omega-phi-kappa)"),
           "points.csv": format_table(points, comment=head + f"true points ({unit_l})"),
           "image_points.csv": format_table(image, comment=head + "noise-free image "
                                            "coordinates (px)")}
    if truth["distances"]:
        d = truth["distances"]
        out["distances.csv"] = format_table(
            {k: [r[k] for r in d] for k in ("from", "to", "true", "value", "sigma")},
            comment=head + f"distances ({unit_l})")
    return out


def write_simulation(des: Design, folder, *, overwrite=False):
    """Write the simulated project into ``folder``: ``<name>.prj`` with its
    tables, ``truth/`` and, with a ``[montecarlo]`` section,
    ``montecarlo.prj``. Returns ``(prj path, project, truth)``."""
    from photogram.project import write_project
    from photogram.project.atomic import atomic_write_text
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    project, truth = simulate_design(des)
    from photogram.project.safe_names import safe_name
    # the design's name (any text) as a file name that stays in the folder
    prj = write_project(project, folder / f"{safe_name(project.name, 'project')}.prj",
                        overwrite=overwrite)
    (folder / "truth").mkdir(exist_ok=True)
    for name, text in _truth_tables(project, truth).items():
        atomic_write_text(folder / "truth" / name, text)
    if des.montecarlo:
        m = des.montecarlo
        step = "orient" if all(not c.free_mask().any() for c in project.cameras.values()) \
            else "calibrate"
        pts = sorted({i.split("@")[0] + "@*" for i in project.points.ids if "@" in i})

        def q(text):                      # a TOML string (any name, quotes escaped)
            return json.dumps(str(text), ensure_ascii=False)
        lines = ["# Monte-Carlo simulation of the simulated network (photogram simulate)",
                 "[project]", f"name = {q(project.name + '-montecarlo')}",
                 f'length_unit = "{project.units.length}"',
                 f'angle_unit = "{project.units.angle}"', "", "[montecarlo]",
                 f"{step} = {q(prj.name)}",
                 "perturb = [" + ", ".join(f'"{p}"' for p in m["perturb"]) + "]",
                 'truth = "simulation"']
        if pts:
            lines += ["points = [" + ", ".join(q(p) for p in pts) + "]", 'align = "plan"']
        lines += [f"runs = {m['runs']}", f"seed = {m['seed']}", f"chunk = {m['chunk']}",
                  f"workers = {m['workers']}", "", "[output]", 'folder = "results/montecarlo"',
                  ""]
        atomic_write_text(folder / "montecarlo.prj", "\n".join(lines))
    return prj, project, truth
