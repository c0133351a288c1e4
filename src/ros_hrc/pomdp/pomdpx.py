"""POMDPX (SARSOP ``doc/POMDPX``, version 1.0): read and write.

Reading: :func:`load` / :func:`loads` (:mod:`ros_hrc.pomdp.pomdpx_reader`, whose docstring says
what is read and checked; a factored file becomes one flat model as
:mod:`ros_hrc.pomdp.pomdpx_flat` says). Writing: :func:`dump` / :func:`save`
(:mod:`ros_hrc.pomdp.pomdpx_writer`). A model written and read again has bit-identical tables.
:func:`rowwise_kron` is the product that makes a factored model's flat tables.
"""
from ros_hrc.pomdp.pomdpx_reader import load, loads
from ros_hrc.pomdp.pomdpx_tables import rowwise_kron
from ros_hrc.pomdp.pomdpx_writer import dump, save

__all__ = ["load", "loads", "dump", "save", "rowwise_kron"]
