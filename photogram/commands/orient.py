"""`photogram orient PROJECT`: exterior orientation with fixed cameras."""

import logging

from photogram.commands.bundle import orient


def run(project, args=None):
    folder, result = orient(project)
    s = result.summary
    logging.getLogger("photogram").info(
        "orient: %s after %d iterations, sigma0 %.4f, redundancy %d; results in %s",
        s["status"], s["iterations"], s["sigma0"], s["redundancy"], folder)
    return 0
