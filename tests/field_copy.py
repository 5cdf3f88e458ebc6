"""A writable copy of the example field project (projects/field) with the
nominal interior orientation (the lab calibration need not have run), for
tests that change its tables or settings."""

import re
import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIELD = ROOT / "projects" / "field"


def field_copy(tmp_path, adjustment=None, **replace):
    """Copy projects/field into ``tmp_path/field``; ``adjustment`` (dict)
    overrides or adds keys of [adjustment] (values written as TOML);
    ``replace`` maps a table name to a function ``text -> text``.
    Returns the path of field.prj."""
    dst = Path(tmp_path) / "field"
    shutil.copytree(FIELD, dst, ignore=shutil.ignore_patterns("results", "truth"))
    prj = dst / "field.prj"
    text = prj.read_text().replace('"../lab/results/cameras.toml"', '"cameras-nominal.toml"')
    for key, value in (adjustment or {}).items():
        line = f"{key} = {value}"
        pattern = re.compile(rf"^{key} = .*$", re.M)
        text = pattern.sub(line, text) if pattern.search(text) else \
            text.replace("[adjustment]\n", f"[adjustment]\n{line}\n")
    prj.write_text(text)
    for name, change in replace.items():
        path = dst / name
        path.write_text(change(path.read_text()))
    return prj
