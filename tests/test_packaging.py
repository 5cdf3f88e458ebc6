"""The installed package must contain every subpackage of photogram/."""

import configparser
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def listed_packages():
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    return {p.strip() for p in cfg["options"]["packages"].split() if p.strip()}


def test_every_subpackage_is_listed_in_setup_cfg():
    found = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for init in (ROOT / "photogram").rglob("__init__.py")
    }
    missing = found - listed_packages()
    assert not missing, f"add these to [options] packages in setup.cfg: {sorted(missing)}"


def test_cli_is_installed_as_photogram_cli_not_cli():
    packages = listed_packages()
    assert "photogram_cli" in packages
    assert "cli" not in packages


def test_lower_layers_do_not_import_cli():
    offenders = [
        str(f.relative_to(ROOT))
        for f in (ROOT / "photogram").rglob("*.py")
        if "photogram_cli" in f.read_text(encoding="utf-8")
    ]
    assert not offenders
