"""`photogram calibrate PROJECT`: self-calibrating bundle adjustment; on a
board project (one with ``[board]``) the multi-camera rig calibration of
:mod:`photogram.commands.board`."""

from photogram.commands.bundle import announce, calibrate, wants_report


def run(project, args=None):
    if getattr(project, "board", None) is not None:
        from photogram.commands.board import run as run_board
        return run_board(project, args)
    folder, result = calibrate(project, report=wants_report(args))
    announce("calibrate", folder, result.summary, args)
    return 0
