"""The run's channel table: every signal's tracking channels under one satellite key.

A run has one channel manager per signal (receiver.tracking.channels.ChannelManager), each keeping its
channels by the signal's PRN.  The navigation engine, the run writer and the vector tracker key satellites
the run's way: by the signal's PRN in a run over one signal, by satellite key (receiver.gnss.satid.sat_key:
BeiDou PRN p is 400 + p) in a run over several.  :class:`ChannelTable` is the one place that maps between
the two:

* as a mapping it is every channel of the run keyed by the run's key (the managers' dicts stay the owners:
  setting or deleting an entry changes the manager's dict) -- what the pipeline's chunk loop and the vector
  tracker use;
* :meth:`ChannelTable.key` / :meth:`ChannelTable.split` turn a signal's PRN into the run's key and back;
* :meth:`ChannelTable.signal_view` is what one signal's channel manager sees of a run-keyed object (the
  navigation engine, the run writer): the same object taking and giving the signal's PRNs.
"""
from __future__ import annotations

import copy
from collections.abc import MutableMapping

from ..gnss.satid import sat_key, split_key


class ChannelTable(MutableMapping):
    """Every channel of a run keyed by the run's satellite key (see the module docstring).  ``multi``: a run
    over several signals (keys are sat_key's); else keys are the one signal's PRNs."""

    def __init__(self, multi: bool):
        self.multi = multi
        self._by: dict[str, dict] = {}      # signal's system letter -> {signal PRN: Channel} (a manager's dict)

    def add(self, system: str, channels: dict) -> None:
        """Register the channel dict (keyed by PRN) of the signal whose RINEX letter is ``system``."""
        self._by[system] = channels

    def key(self, system: str, prn: int) -> int:
        """The run's key of PRN ``prn`` of the signal ``system``."""
        return sat_key(system, prn) if self.multi else prn

    def split(self, key: int) -> tuple[str, int]:
        """(signal system letter, signal PRN) of a run key."""
        if self.multi:
            return split_key(key)
        return next(iter(self._by)), key

    def signal_view(self, target, system: str):
        """What the channel manager of signal ``system`` sees of the run-keyed ``target`` (navigation engine,
        run writer; None stays None): ``target`` itself in a one-signal run."""
        if not self.multi or target is None:
            return target
        return _SignalView(target, system)

    # ------------------------------------------------------------------ the mapping
    def _dict(self, key):
        letter, prn = self.split(key)
        return self._by[letter], prn

    def __getitem__(self, key):
        d, prn = self._dict(key)
        return d[prn]

    def __setitem__(self, key, ch):
        d, prn = self._dict(key)
        d[prn] = ch

    def __delitem__(self, key):
        d, prn = self._dict(key)
        del d[prn]

    def __iter__(self):
        for letter, d in self._by.items():
            for prn in list(d):
                yield self.key(letter, prn)

    def __len__(self):
        return sum(len(d) for d in self._by.values())


class _SignalView:
    """A run-keyed object (navigation engine or run writer) as one signal's channel manager sees it in a run
    over several signals: the calls take the signal's PRNs, ``channels`` holds the signal's satellites keyed
    by PRN; every other attribute is the object's."""

    def __init__(self, target, system: str):
        self._t, self._sys = target, system

    def _k(self, prn):
        return sat_key(self._sys, prn)

    def __getattr__(self, name):
        return getattr(self._t, name)

    # navigation engine
    @property
    def channels(self):
        """The navigation engine's satellite channels of this signal, keyed by PRN."""
        return {p - self._k(0): c for p, c in self._t.channels.items() if split_key(p)[0] == self._sys}

    def add_records(self, prn, recs, bit_offset, dll_hold_s=0.0):
        """NavigationEngine.add_records of the signal's PRN."""
        self._t.add_records(self._k(prn), recs, bit_offset, dll_hold_s)

    def suspend(self, prn):
        """NavigationEngine.suspend of the signal's PRN."""
        self._t.suspend(self._k(prn))

    def resume(self, prn, *a, **k):
        """NavigationEngine.resume of the signal's PRN."""
        self._t.resume(self._k(prn), *a, **k)

    def satellite_los(self, prn, s):
        """NavigationEngine.satellite_los of the signal's PRN."""
        return self._t.satellite_los(self._k(prn), s)

    def set_noncoherent(self, prn, from_sample):
        """NavigationEngine.set_noncoherent of the signal's PRN."""
        self._t.set_noncoherent(self._k(prn), from_sample)

    # run writer
    def append_channel(self, prn, recs):
        """RunWriter.append_channel of the signal's PRN."""
        self._t.append_channel(self._k(prn), recs)

    def write_acquisition(self, results, attrs=None):
        """RunWriter.write_acquisition with the results' PRNs turned into satellite keys."""
        out = []
        for r in results:
            r = copy.copy(r)
            r.prn = self._k(r.prn)
            out.append(r)
        self._t.write_acquisition(out, attrs)
