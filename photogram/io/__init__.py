"""Readers and writers of foreign formats (DBAT, ...).

Each format lives in its own module (``photogram.io.dbat``, ...) and builds
or reads the dataclasses of :mod:`photogram.project.model`.
"""
