"""Readers and writers of foreign formats (docs/interoperability.md).

Each format lives in its own module and builds or reads the dataclasses of
:mod:`photogram.project.model`:

=====================  ==========================================================
``dbat``               DBAT projects -> project (their table parsers: project.dbat_tables)
``dbat_script``        DBAT XML scripts -> project
``dbat_script_ops``    their <operations> (initial values, estimated parameters, datum), <prior_eo>
``pmexport``           PhotoModeler text exports as PhotoModeler writes them -> project
``pose2sim``           Pose2Sim / anipose calibration TOML, both ways
``opencv_fs``          OpenCV FileStorage calibration (YAML/XML/JSON), both ways
``colmap``             COLMAP models (binary and text, rigs), both ways; its parts:
``colmap_records``     the records of the files; ``colmap_text``, ``colmap_binary``
``colmap_cameras``     COLMAP's camera models <-> photogram's (exact both ways)
``colmap_rigs``        COLMAP >= 3.12 rigs and frames: the image poses
``bal``                BAL problem files (the engine's BAL mode: bundle.bal)
``bal_import``         BAL problems (read by ``bal``) -> project
``ply``                object points with sigmas (PLY)
``trc``                OpenSim marker files
``trajectories``       TRC, C3D, OpenSim .mot and CSV from intersect results
``mocap_results``      the results folder of ``photogram mocap`` as trajectories
``trajectory_data``    the Trajectories both of them load
``export_source``      a project or results folder as the source of an export
``targets``            chessboard / ChArUco / circle-grid images -> calibration project
``exchange``           what they share: OpenCV views, project folders, results
``formats``            the registry behind ``photogram import`` / ``photogram export``
=====================  ==========================================================
"""
