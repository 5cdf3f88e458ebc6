"""When finished Monte-Carlo runs may be reused: the manifest of a samples folder.

A run of a chain depends on every input file the chain reads (the
adjustment project and its tables, the cameras files it takes from a
calibration, the calibration's ``covariance.npz``, the intersect project and
its tables, the ``truth/`` tables of a simulation), on the settings of the
``[montecarlo]`` section that change its numbers (seed, chunk size,
perturbations, truth, steps, collected points, alignment, interior
covariance folder) and on the program that computes it. The manifest
(``samples/manifest.json``) records all of them, the files by the SHA-256 of
their content, and every chunk file carries the digest of the manifest it
was computed under.

A new start reuses finished chunks only when the manifest is identical:

* any difference (a control coordinate edited in a points table,
  ``sigma_image`` changed in a project file, another seed, another
  photogram version, ...) means **recompute everything**, with one line
  naming what changed;
* ``--force`` always recomputes;
* a chunk whose digest is not that of the current manifest (e.g. written by
  an older run still going) is never read.

The number of runs is not part of the manifest: run ``i`` has the same
numbers for any number of runs (:func:`photogram.montecarlo.execute.seeds_for`),
so raising ``--runs`` reuses what is done.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["FORMAT", "file_digest", "project_files", "fingerprint", "manifest_digest",
           "why_different"]

#: version of the manifest layout (format 1 had no file digests)
FORMAT = 2


def file_digest(path) -> str:
    """SHA-256 (hex) of a file's content; ``"missing"`` if it cannot be read."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return "missing"
    return h.hexdigest()


def project_files(project) -> list:
    """The files a project was read from: its .prj and every table and
    cameras file it names (``project.sources``)."""
    out = [Path(project.path)]
    out += [Path(p) for p in getattr(project, "sources", {}).values() if p]
    return out


def _key(path) -> str:
    return str(Path(path).resolve())


def fingerprint(chain, *, seed: int, chunk: int) -> dict:
    """Everything the runs of ``chain`` depend on (module docstring)."""
    import photogram
    s = chain.settings

    def where(p):
        return _key(p) if p is not None else None

    names = hashlib.sha256("\n".join(chain.outputs.names).encode()).hexdigest()
    files = {_key(p): file_digest(p) for p in getattr(chain, "input_files", ())}
    return {"format": FORMAT, "photogram": photogram.__version__,
            "settings": {"seed": int(seed), "chunk": int(chunk),
                         "perturb": sorted(s.perturb), "truth": s.truth,
                         "orient": where(s.orient), "calibrate": where(s.calibrate),
                         "intersect": where(s.intersect), "points": list(s.points),
                         "align": s.align,
                         "interior_covariance": where(s.interior_covariance)},
            "outputs": names,
            "files": dict(sorted(files.items()))}


def manifest_digest(fp: dict) -> str:
    """Short digest of a fingerprint (written into every chunk file)."""
    text = json.dumps(fp, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _names(paths, limit=3):
    paths = sorted(paths)
    shown = ", ".join(Path(p).name for p in paths[:limit])
    return shown + (f" and {len(paths) - limit} more" if len(paths) > limit else "")


def why_different(old, new: dict) -> str | None:
    """What differs between the manifest ``old`` (None: missing or unreadable)
    and ``new``, as a short text; None if they are the same."""
    if old == new:
        return None
    if not isinstance(old, dict) or old.get("format") != new["format"]:
        return "the samples folder has no manifest of this photogram version"
    parts = []
    if old.get("photogram") != new["photogram"]:
        parts.append(f"photogram {old.get('photogram')} computed them, this is "
                     f"{new['photogram']}")
    o_set, n_set = old.get("settings") or {}, new["settings"]
    changed = [k for k in n_set if o_set.get(k) != n_set[k]]
    for k in changed[:3]:
        parts.append(f"{k} was {o_set.get(k)!r}, is {n_set[k]!r}")
    o_files, n_files = old.get("files") or {}, new["files"]
    edited = [p for p in n_files if p in o_files and o_files[p] != n_files[p]]
    added = [p for p in n_files if p not in o_files]
    gone = [p for p in o_files if p not in n_files]
    if edited:
        parts.append(f"{_names(edited)} changed")
    if added:
        parts.append(f"now also reads {_names(added)}")
    if gone:
        parts.append(f"no longer reads {_names(gone)}")
    if old.get("outputs") != new["outputs"] and not parts:
        parts.append("the chain's output quantities changed")
    return "; ".join(parts) or "the manifest differs"
