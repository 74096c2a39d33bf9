"""The run's channel table (receiver/tracking/table.py): one satellite-keyed view of every signal's channel
manager dict, and the PRN-keyed view a signal's manager has of the run-keyed navigation engine / writer."""
from types import SimpleNamespace

from receiver.gnss.satid import BDS_KEY
from receiver.tracking.table import ChannelTable


def test_one_signal_run_keys_are_prns_and_views_are_the_objects():
    gps = {5: "ch5", 193: "qzs"}
    t = ChannelTable(multi=False)
    t.add("G", gps)
    assert list(t) == [5, 193] and t[193] == "qzs" and len(t) == 2
    t[7] = "ch7"                                    # writes through to the manager's dict
    del t[5]
    assert gps == {193: "qzs", 7: "ch7"}
    nav = object()
    assert t.signal_view(nav, "G") is nav and t.signal_view(None, "G") is None
    bds = ChannelTable(multi=False)                 # a BeiDou-only run: still the signal's PRNs
    bds.add("C", {12: "c12"})
    assert bds.key("C", 12) == 12 and bds.split(12) == ("C", 12) and bds[12] == "c12"


def test_several_signals_share_one_satellite_key_space():
    gps, bds = {5: "g5"}, {12: "c12"}
    t = ChannelTable(multi=True)
    t.add("G", gps)
    t.add("C", bds)
    assert list(t) == [5, BDS_KEY + 12] and t[BDS_KEY + 12] == "c12"
    assert t.key("C", 12) == BDS_KEY + 12 and t.split(BDS_KEY + 12) == ("C", 12)
    t[BDS_KEY + 3] = "c3"                           # lands in the BeiDou manager's dict, keyed by PRN
    del t[5]
    assert bds == {12: "c12", 3: "c3"} and gps == {}


class _Engine:
    """A run-keyed stand-in for the navigation engine and the run writer (records the keys it is given)."""

    def __init__(self):
        self.channels = {5: "nav-g5", BDS_KEY + 12: "nav-c12"}
        self.calls = []
        self.fs = 4e6

    def add_records(self, key, recs, bit_offset, dll_hold_s=0.0):
        self.calls.append(("add_records", key))

    def suspend(self, key):
        self.calls.append(("suspend", key))

    def append_channel(self, key, recs):
        self.calls.append(("append_channel", key))

    def write_acquisition(self, results, attrs=None):
        self.calls.append(("write_acquisition", [r.prn for r in results]))


def test_signal_view_translates_prns_to_satellite_keys():
    eng = _Engine()
    t = ChannelTable(multi=True)
    view = t.signal_view(eng, "C")
    assert view.channels == {12: "nav-c12"}         # only BeiDou's satellites, by PRN
    assert t.signal_view(eng, "G").channels == {5: "nav-g5"}
    view.add_records(12, None, 0)
    view.suspend(12)
    view.append_channel(3, None)
    res = [SimpleNamespace(prn=12), SimpleNamespace(prn=3)]
    view.write_acquisition(res)
    assert eng.calls == [("add_records", BDS_KEY + 12), ("suspend", BDS_KEY + 12),
                         ("append_channel", BDS_KEY + 3), ("write_acquisition", [BDS_KEY + 12, BDS_KEY + 3])]
    assert [r.prn for r in res] == [12, 3]          # the manager's results are not changed
    assert view.fs == 4e6                           # everything else is the object's own
