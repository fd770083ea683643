"""`common.beside`: a function run in a forked child gives the value it gives here,
raises here the error it raised there, and a child that dies is an error, not a hang."""

import os
import signal

import numpy as np
import pytest

import common.beside as beside_module
from common.beside import beside, forking
from common.errors import InputError

needs_fork = pytest.mark.skipif(not forking(), reason="no fork start method or one CPU: runs serially")


def draws(seed, n):
    return np.random.default_rng(seed).standard_normal(n).cumsum()


def refuse(name):
    raise InputError(f"no bending variant '{name}'")


def die():
    os.kill(os.getpid(), signal.SIGKILL)


@needs_fork
def test_the_child_computes_what_this_process_computes():
    with beside(draws, 3, 100_000) as later:
        here = draws(3, 100_000)
        there = later.result()
    assert there.tobytes() == here.tobytes()


@needs_fork
def test_an_error_in_the_child_is_raised_here_with_its_message():
    with pytest.raises(InputError, match="no bending variant 'stiff'") as caught:
        with beside(refuse, "stiff") as later:
            later.result()
    assert "refuse" in str(caught.value.__cause__)          # the child's traceback


@needs_fork
def test_a_child_that_dies_is_an_error_not_a_hang():
    with pytest.raises(RuntimeError, match="stopped without an answer"):
        with beside(die) as later:
            later.result()


def test_without_fork_the_function_runs_here_when_asked(monkeypatch):
    monkeypatch.setattr(beside_module, "forking", lambda: False)
    calls = []
    with beside(calls.append, 1) as later:
        assert calls == []
        later.result()
    assert calls == [1]
    with pytest.raises(InputError, match="'stiff'"):
        with beside(refuse, "stiff") as later:
            later.result()
