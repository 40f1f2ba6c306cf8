"""Spools keep long results on disk and read back exactly; replay's JSON writer streams the text json.dump writes."""
import io
import json
import math
import pickle

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mjccd import replay, spool

SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=False),
                    st.text(max_size=8))
JSON = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                    max_leaves=20)


@settings(max_examples=200, deadline=None)
@given(JSON)
def test_write_json_is_json_dump_indent_1(value):
    out = io.StringIO()
    replay.write_json(out, value)
    assert out.getvalue() == json.dumps(value, indent=1)


def test_write_json_streams_iterables():
    out = io.StringIO()
    replay.write_json(out, {"a": (x for x in range(3)), "b": (x for x in ()), "c": spool.JsonSpool([{"k": [1]}])})
    assert out.getvalue() == json.dumps({"a": [0, 1, 2], "b": [], "c": [{"k": [1]}]}, indent=1)


def test_json_spool_reads_like_a_list():
    items = [{"frame": k, "time": k / 3.0, "point": [math.pi * k, -0.0, 1e-300]} for k in range(5000)]
    s = spool.JsonSpool()
    for item in items[:10]:
        s.append(item)
    assert s[3] == items[3] and s[-1] == items[9] and s[2:8:3] == items[2:8:3]  # a read, then more appends
    for item in items[10:]:
        s.append(item)
    assert len(s) == 5000 and s == items and items == s and list(s) == items  # bit-exact floats, past a block
    assert s[::-1] == items[::-1] and s != items[:-1] and bool(spool.JsonSpool()) is False
    assert pickle.loads(pickle.dumps(s)) == items
    try:
        s[5000]
    except IndexError:
        pass
    else:
        raise AssertionError("index past the end")


def test_array_spool_keeps_records_in_order():
    s = spool.ArraySpool(replay.RUN_DTYPE)
    records = [(k % 7, k, k + 2, k * 0.5, k * 0.5 + 1.0) for k in range(spool.BUFFERED * 2 + 5)]
    for r in records:
        s.append(r)
    got = s.array()
    assert len(s) == len(records) and got.tolist() == records
    assert pickle.loads(pickle.dumps(s)).array().tolist() == records
    np.testing.assert_array_equal(spool.ArraySpool(replay.RUN_DTYPE).array(), np.zeros(0, replay.RUN_DTYPE))
