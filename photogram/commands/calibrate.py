"""`photogram calibrate PROJECT`: self-calibrating bundle adjustment."""

from photogram.commands.bundle import announce, calibrate


def run(project, args=None):
    folder, result = calibrate(project)
    announce("calibrate", folder, result.summary, args)
    return 0
