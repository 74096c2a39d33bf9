"""Each variant list has one owner, the registry of the module that implements the variants; the receiver
config schema (which sits below those modules and cannot import them) must offer exactly the registered
names, and the schema's help must not drift from them."""
from receiver.config import RECEIVER_SCHEMA


def _choices(dotted):
    node = RECEIVER_SCHEMA
    for part in dotted.split("."):
        node = node[part]
    return tuple(node.choices)


def test_input_formats_are_the_readers():
    from receiver.config import INPUT_FORMAT_ALIASES, INPUT_FORMATS
    from receiver.source.io import ALIASES, BIT_ORDERS, ENCODINGS, FORMATS
    assert set(INPUT_FORMATS) == set(FORMATS) and set(INPUT_FORMAT_ALIASES) == set(ALIASES)
    assert set(_choices("input.format")) == set(FORMATS) | set(ALIASES)
    assert set(_choices("input.bit_order")) == set(BIT_ORDERS)
    assert set(_choices("input.encoding")) == set(ENCODINGS)
    from receiver.config import REAL_FORMAT_ALIASES
    assert set(REAL_FORMAT_ALIASES) == {a for a, f in ALIASES.items() if not FORMATS[f].complex}


def test_signals_are_the_signal_registry():
    from receiver.gnss.registry import SIGNAL_NAMES, get_signal
    assert set(_choices("signal")) == set(SIGNAL_NAMES)
    for name in SIGNAL_NAMES:
        assert get_signal(name).name == name


def test_config_prn_sets_are_the_signals_prns():
    from receiver.config import SIGNAL_PRNS
    from receiver.gnss.registry import SIGNAL_NAMES, get_signal
    assert set(SIGNAL_PRNS) == set(SIGNAL_NAMES)
    for name in SIGNAL_NAMES:
        assert tuple(SIGNAL_PRNS[name]) == tuple(get_signal(name).prns)


def test_carrier_loops_are_the_carrier_registry():
    from receiver.tracking.carrier import REGISTRY
    assert set(_choices("tracking.carrier.variant")) == set(REGISTRY) | {"auto"}    # auto picks per channel
    assert set(_choices("tracking.carrier.auto_weak")) == set(_choices("tracking.carrier.auto_strong")) \
        == set(REGISTRY)
    assert all(cls.name == name for name, cls in REGISTRY.items())


def test_vector_variants_are_the_vector_registry():
    from receiver.tracking.vector import REGISTRY
    assert set(_choices("vector.variant")) == set(REGISTRY)


def test_oscillator_classes_are_the_clock_table():
    from receiver.gnss.clock import OSCILLATORS
    assert set(_choices("navigation.filter_clock")) == set(OSCILLATORS)
    assert set(_choices("vector.clock_class")) == set(OSCILLATORS)
