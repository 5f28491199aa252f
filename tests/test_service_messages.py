"""The protocol's parser alone: whatever text arrives, a checked message or a ProtocolError with one line, never
anything else; and the fast path for touches agrees with the general checks."""

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st
from ultraglide.apps.service import protocol as p

JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=20),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
                    max_leaves=20)


@given(st.text(max_size=200))
def test_any_text_is_a_message_or_one_line_refused(text):
    try:
        message = p.parse(text)
    except p.ProtocolError as error:
        assert error.code in {p.BAD_MESSAGE, p.TOO_BIG} and "\n" not in str(error) and str(error)
    else:
        assert message.type in p.SPECS


@given(st.sampled_from(sorted(p.SPECS)), st.dictionaries(st.sampled_from(["x", "y", "t", "phase", "view", "sprite",
                                                                            "texture", "width", "height", "z",
                                                                            "pressure", "pointer", "protocol"]),
                                                           JSON, max_size=6))
def test_messages_of_each_type_with_any_fields_are_checked_or_refused(kind, fields):
    try:
        message = p.parse(json.dumps({"type": kind, **fields}))
    except p.ProtocolError as error:
        assert "\n" not in str(error)
    else:
        for key, (check, _) in p.SPECS[kind].items():
            if key in message.fields:
                assert check(fields[key], key) == message[key]  # what the general checks give


@given(x=st.floats(-2e6, 2e6, allow_nan=False) | st.integers(-3_000_000, 3_000_000) | st.booleans() | st.text(),
       pressure=st.none() | st.floats(-1, 2, allow_nan=False) | st.booleans(),
       pointer=st.none() | st.integers(-2**40, 2**40) | st.floats(allow_nan=False),
       view=st.none() | st.text(max_size=70))
def test_the_touch_fast_path_accepts_exactly_what_the_general_checks_accept(x, pressure, pointer, view):
    data = {"type": "touch", "phase": "move", "x": x, "y": 1.0}
    for key, value in (("pressure", pressure), ("pointer", pointer), ("view", view)):
        if value is not None:
            data[key] = value
    fast = p._touch_fast(data, None)
    try:
        general = p.parse(json.dumps(data, allow_nan=False))
    except p.ProtocolError:
        general = None
    except ValueError:  # not strict JSON (an infinite pointer): no client can send it, and the fast path refuses it
        assert fast is None
        return
    if fast is not None:
        assert general is not None and fast.fields == general.fields
    spec = p.SPECS["touch"]
    try:
        expected = {key: check(data[key], key) for key, (check, _) in spec.items() if key in data}
    except ValueError:
        expected = None
    assert (general.fields if general else None) == expected


def test_a_touch_with_every_field_right_comes_as_typed_values():
    text = json.dumps({"type": "touch", "phase": "down", "x": 3, "y": 4.5, "t": 12.0, "pressure": 0.5,
                       "pointer": 7, "view": "main", "pointer_type": "pen"})
    message = p.parse(text)
    assert message.fields == {"phase": "down", "x": 3.0, "y": 4.5, "t": 12.0, "pressure": 0.5, "pointer": 7,
                              "view": "main", "pointer_type": "pen"}
    with pytest.raises(p.ProtocolError, match="'pressure' must be a number from 0 to 1"):
        p.parse(text.replace('"pressure": 0.5', '"pressure": 1.5'))


def test_a_client_may_send_its_burst_then_the_rate():
    import time

    from ultraglide.apps.service.server import RATE_BURST, RATE_PER_S, Session

    started = time.perf_counter()
    session = Session(connection=None, number=1)
    allowed = sum(session.allow(time.perf_counter()) for _ in range(int(RATE_BURST) + 3000))
    elapsed = time.perf_counter() - started
    assert RATE_BURST <= allowed <= RATE_BURST + RATE_PER_S * elapsed + 1
