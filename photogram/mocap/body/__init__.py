"""The athlete's body: skeletons (joint names, limbs, left/right pairs, the
mappings between detector skeletons and SKI24) and the segment masses and
centres of mass of de Leva (1996).

The bottom of :mod:`photogram.mocap`: imports no other part of it (only
:mod:`photogram.errors` and numpy). Empty on purpose: importing the package
loads no module.
"""
