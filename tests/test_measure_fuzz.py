"""The target-field reader against malformed descriptions: every mutation
of a valid description is read or refused with an InputError (one line),
never a traceback."""

import random
from pathlib import Path

import pytest

from photogram.errors import InputError
from photogram.measure.field import read_field

SHEET = Path(__file__).resolve().parents[1] / "projects" / "camcal" / "sheet.toml"
VALUES = ['"x"', "-1", "0", "1e309", "nan", "[]", "[1, 2]", '["a", "b", "c"]', "true",
          "{ a = 1 }", '"11x1"', '"D{row}"', '"{bad"', "3.5", '""', "[0, 0, 0, 0]"]


def _mutations(n=300, seed=3):
    rng = random.Random(seed)
    lines = SHEET.read_text().splitlines()
    keyed = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
    for _ in range(n):
        new = list(lines)
        for i in rng.sample(keyed, rng.randint(1, 3)):
            key = new[i].split("=")[0]
            new[i] = f"{key}= {rng.choice(VALUES)}"
        if rng.random() < 0.2:
            del new[rng.choice(keyed)]
        yield "\n".join(new) + "\n"


def test_mutated_descriptions_are_read_or_refused(tmp_path):
    path = tmp_path / "sheet.toml"
    read, refused = 0, 0
    for text in _mutations():
        path.write_text(text)
        try:
            read_field(path)
            read += 1
        except InputError as exc:
            assert "\n" not in exc.one_line() and str(path) in exc.one_line()
            refused += 1
    print(f"{read} read, {refused} refused, 0 tracebacks")
    assert refused > 100
