"""`photogram calibrate PROJECT`: self-calibrating bundle adjustment."""

import logging

from photogram.commands.bundle import calibrate


def run(project, args=None):
    folder, result = calibrate(project)
    s = result.summary
    logging.getLogger("photogram").info(
        "calibrate: %s after %d iterations, sigma0 %.4f, redundancy %d; results in %s",
        s["status"], s["iterations"], s["sigma0"], s["redundancy"], folder)
    return 0
