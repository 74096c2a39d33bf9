"""Snapshot positioning (coarse-time navigation) from a few milliseconds of signal: acquisition tuned to the
snapshot (:mod:`.acquire`), the run over one or many snapshots of a file (:mod:`.run`) and the command
``gnssrx snapshot`` (:mod:`.cli`).  The coarse-time solver is receiver/navigation/snapshot.py."""
