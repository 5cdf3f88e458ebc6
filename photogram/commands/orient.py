"""`photogram orient PROJECT`: exterior orientation with fixed cameras."""

from photogram.commands.bundle import announce, orient


def run(project, args=None):
    folder, result = orient(project)
    announce("orient", folder, result.summary, args)
    return 0
