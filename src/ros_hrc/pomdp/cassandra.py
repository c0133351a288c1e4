"""Cassandra's ``.pomdp`` text format (pomdp.org, pomdp-solve, SARSOP ``examples/POMDP``).

Reading: :func:`load` / :func:`loads` (:mod:`ros_hrc.pomdp.cassandra_reader`, whose docstring
says what is read and checked). Writing: :func:`dump` / :func:`save`
(:mod:`ros_hrc.pomdp.cassandra_writer`). A model written and read again has bit-identical
tables.
"""
from ros_hrc.pomdp.cassandra_reader import load, loads
from ros_hrc.pomdp.cassandra_writer import dump, save

__all__ = ["load", "loads", "dump", "save"]
