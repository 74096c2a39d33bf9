"""Each choice list has one owner, the registry of the module that implements the choices; the stage's
config fragment offers exactly the registered names (it takes them from the registry), and the schema
assembled from the fragments (receiver/schema.py) is the one the receiver validates against."""
from receiver.schema import RECEIVER_SCHEMA, SIGNAL_PRNS, load_receiver_config


def _choices(dotted):
    node = RECEIVER_SCHEMA
    for part in dotted.split("."):
        node = node[part]
    return tuple(node.choices)


def test_input_formats_are_the_readers():
    from receiver.source.config import REAL_FORMAT_ALIASES
    from receiver.source.io import ALIASES, BIT_ORDERS, ENCODINGS, FORMATS
    assert _choices("input.format") == tuple(FORMATS) + tuple(ALIASES)
    assert _choices("input.bit_order") == tuple(BIT_ORDERS)
    assert _choices("input.encoding") == tuple(ENCODINGS)
    assert set(REAL_FORMAT_ALIASES) == {"byte", "short", "float", "rf32_le", "ri16_le", "ri8"}
    for name in FORMATS:                       # every reader's name loads
        assert load_receiver_config(None, [f"input.format={name}", "input.if_hz=1e5"]).input.format == name


def test_signals_are_the_signal_registry():
    from receiver.gnss.registry import SIGNAL_NAMES, get_signal
    assert _choices("signal") == tuple(SIGNAL_NAMES)
    for name in SIGNAL_NAMES:
        assert get_signal(name).name == name


def test_config_prn_sets_are_the_signals_prns():
    from receiver.gnss.registry import SIGNAL_NAMES, get_signal
    assert set(SIGNAL_PRNS) == set(SIGNAL_NAMES)
    assert SIGNAL_PRNS["gps_l1ca"] == tuple(range(1, 33)) + tuple(range(193, 203))   # GPS + QZSS J01-J10
    assert SIGNAL_PRNS["bds_b1i"] == tuple(range(1, 64))
    for name in SIGNAL_NAMES:
        assert tuple(SIGNAL_PRNS[name]) == tuple(get_signal(name).prns)


def test_carrier_loops_are_the_carrier_registry():
    from receiver.tracking.carrier import REGISTRY
    assert _choices("tracking.carrier.auto_weak") == _choices("tracking.carrier.auto_strong") == tuple(REGISTRY)
    assert all(cls.name == name for name, cls in REGISTRY.items())


def test_cn0_estimators_are_the_channels():
    from receiver.tracking.scalar import CN0_ESTIMATORS
    assert _choices("tracking.cn0_estimator") == tuple(CN0_ESTIMATORS)


def test_vector_variants_are_the_vector_registry():
    from receiver.tracking.vector import REGISTRY
    assert _choices("vector.variant") == tuple(REGISTRY)


def test_oscillator_classes_are_the_clock_table():
    from receiver.gnss.clock import OSCILLATORS
    assert _choices("navigation.filter_clock") == tuple(OSCILLATORS)
    assert _choices("vector.clock_class") == tuple(OSCILLATORS)


def test_navigation_choices_are_the_solvers():
    from receiver.navigation.pvt_filter import KINDS
    from receiver.navigation.wls_jit import WEIGHTING
    from receiver.runfile.writer import COMPRESSION
    assert _choices("navigation.weighting") == tuple(WEIGHTING)
    assert _choices("navigation.filter") == ("wls",) + KINDS
    assert _choices("output.compression") == tuple(COMPRESSION)


def test_partial_navigation_configs_take_the_schema_defaults():
    """NavSolver / PvtFilter accept partial config objects; what they leave out is the schema's default
    (one place states it: receiver/navigation/config.py), e.g. navigation.filter wls (no filter)."""
    from types import SimpleNamespace
    from receiver.navigation.pvt import NavSolver
    from receiver.navigation.pvt_filter import PvtFilter, make_pvt_filter
    nav = RECEIVER_SCHEMA["navigation"]
    s = NavSolver(SimpleNamespace())
    assert (s.elevation_mask_deg, s.weighting, s.max_pdop) == (nav["elevation_mask_deg"].default,
                                                               nav["weighting"].default, nav["max_pdop"].default)
    assert make_pvt_filter(SimpleNamespace()) is None                   # the default filter: wls
    f = PvtFilter.from_config(SimpleNamespace(filter="ckf"))
    assert (f.kind, f.accel_psd, f.reset_m) == ("ckf", nav["filter_accel_psd"].default,
                                                 nav["filter_reset_m"].default)
