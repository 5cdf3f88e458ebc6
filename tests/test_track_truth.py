"""The truth check of photogram track (simulated videos): ski labels."""

import numpy as np
import pandas as pd

from photogram.track.truth_check import ski_errors


def _truth(sep_tip):
    rows = []
    for st in ("S1", "S2"):
        rows.append((st, 1, "001", "L1", 100.0, 100.0, 200.0, 100.0))
        rows.append((st, 1, "001", "L2", 100.0, 100.0, 200.0, 100.0 + sep_tip))
    return pd.DataFrame(rows, columns=["station", "frame", "exposure", "ski", "x_tail",
                                       "y_tail", "x_tip", "y_tip"])


def _line(st, lab, y_tail, y_tip):
    x = np.linspace(105, 195, 10)
    y = y_tail + (x - 100) / 100 * (y_tip - y_tail)
    return pd.DataFrame({"exposure": "001", "station": st, "line": lab, "x": x, "y": y})


def test_a_line_on_the_other_ski_is_wrong_a_line_on_both_is_not():
    # skis 6 px apart at the tip: S1's L1 measured on L2 is a wrong label
    t = _truth(6.0)
    tracked = pd.concat([_line("S1", "L1", 100.0, 106.0), _line("S2", "L1", 100.0, 100.0)])
    r = ski_errors(tracked, t)
    assert r["n_wrong_label"] == 1 and r["n_lines"] == 1 and r["n_near_both"] == 0
    assert r["rms_deg"] < 1e-9
    # skis 0.6 px apart at the tip: a line 0.4 px off its own ski at the tip
    # (0.2 px on average) is nearer the other but measures its own
    t = _truth(0.6)
    r = ski_errors(_line("S1", "L1", 100.0, 100.4), t)
    assert r["n_wrong_label"] == 0 and r["n_near_both"] == 1 and r["n_lines"] == 1
    assert abs(r["rms_deg"] - np.degrees(np.arctan(0.4 / 100))) < 1e-6
