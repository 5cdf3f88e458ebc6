"""`photogram orient PROJECT`: exterior orientation with fixed cameras."""

from photogram.commands.bundle import announce, orient, wants_report


def run(project, args=None):
    folder, result = orient(project, report=wants_report(args))
    announce("orient", folder, result.summary, args)
    return 0
