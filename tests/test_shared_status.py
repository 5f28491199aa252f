"""The engine's shared status read after its writer died mid-write: a consistent read waits and gives up, a
post-mortem read takes the segment as it is."""

import numpy as np
import pytest
from ultraglide.render.engine import shm
from ultraglide.render.engine.shm import SharedBlock


@pytest.fixture
def block():
    made = SharedBlock.create()
    yield made
    made.close()


def test_a_status_whose_writer_died_between_its_marks_is_read_post_mortem(block):
    block.write_slow({"report": {"exit_status": 0, "lines": ["the plate ran"]}})
    block.fast[shm.SEQ] += 1  # the fast part: its writer died after marking a write begun
    block.slow_header[0] += 1  # the slow part: likewise
    with pytest.raises(TimeoutError):
        block.read_fast()
    with pytest.raises(TimeoutError):
        block.read_slow()
    header, times, history, latency = block.read_fast(post_mortem=True)
    assert header[shm.SEQ] % 2 == 1 and history.shape == block.history.shape
    assert block.read_slow(post_mortem=True) == {"report": {"exit_status": 0, "lines": ["the plate ran"]}}
    assert np.array_equal(block.read_histogram(post_mortem=True), block.histogram)


def test_a_slow_status_torn_mid_bytes_reads_as_empty_post_mortem(block):
    block.write_slow({"a": 1})
    block.slow_header[0] += 1
    block.slow_bytes[0] = ord("x")  # the first bytes of the next status written, the rest not
    assert block.read_slow(post_mortem=True) == {}
