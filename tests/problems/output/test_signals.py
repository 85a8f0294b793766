"""`signals.masked`: an interruption the import machinery turned into an ordinary exception
is still reported as the interruption (exit 130), and nothing else is. `signals.in_main`: a
worker left behind by a signal writes nothing after the main thread's clean-up."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from problems.commands import main as cli
from problems.output import signals


@pytest.fixture
def handlers():
    """The mixvi handlers installed for one test, the previous ones restored after it."""
    before = {s: signal.getsignal(s) for s in signals.SIGNALS}
    hook = sys.unraisablehook
    signals.install()
    yield
    for s, h in before.items():
        signal.signal(s, h)
    sys.unraisablehook = hook
    signals._installed = False


def interrupted_then(error: Exception, keep_context: bool) -> Exception:
    """SIGINT delivered and caught (as compiled module initialisation does), then `error`."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)
    except signals.Interrupted as sig:
        if keep_context:
            error.__context__ = sig
    return error


@pytest.mark.parametrize("keep_context", [True, False])
def test_an_import_error_after_a_signal_is_the_interruption(handlers, keep_context):
    err = interrupted_then(
        ImportError('PyCapsule_Import could not import module "datetime"'), keep_context
    )
    sig = signals.masked(err)
    assert sig is not None and sig.exit_status == 130


def test_an_error_without_a_signal_is_not_masked(handlers):
    assert signals.masked(ImportError("no module named x")) is None
    interrupted_then(ImportError(""), keep_context=False)
    signals.install()  # a new run: the previous run's signal does not count
    assert signals.masked(ImportError("")) is None


def test_main_reports_the_masked_interruption(handlers, monkeypatch, capsys):
    """`mixvi` ends with 130 and one line, not 'internal error' (exit 3)."""

    def failing_import(argv):
        raise interrupted_then(ImportError(""), keep_context=False)

    monkeypatch.setattr(cli, "_dispatch", failing_import)
    assert cli.main(["scenes"]) == 130
    assert capsys.readouterr().err.strip() == "mixvi: interrupted by SIGINT"


def test_a_worker_left_behind_writes_nothing_after_the_clean_up(handlers):
    """A signal while the worker computes: the main thread raises, cleans up and leaves. When
    the worker then reaches its next write (an `in_main` callback; a load path's next step),
    the write must not run: in the worker it would follow the clean-up and make the staging
    folder again (seen as a `.mixvi-tmp-*` left behind after Ctrl-C during a load path, on a
    loaded machine). The old `in_main` ran it as a plain call once the main thread had gone."""
    writes: list[str] = []
    computing, cleaned_up = threading.Event(), threading.Event()
    write = signals.in_main(lambda: writes.append(threading.current_thread().name))

    def work() -> None:
        computing.set()
        cleaned_up.wait(10)  # the step's numerical work outlives the main thread's clean-up
        write()

    def signal_when_computing() -> None:
        computing.wait(10)
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=signal_when_computing).start()
    with pytest.raises(signals.Interrupted):
        signals.interruptible(work)
    worker = signals._abandoned[-1]
    cleaned_up.set()
    worker.join(10)
    assert not worker.is_alive() and writes == []


IN_CALLBACK = """
import signal, sys, time, weakref
from problems.output import signals
signals.install()
if sys.argv[1] == "default-hook":  # the mutation: Python's own hook, which drops it
    sys.unraisablehook = sys.__unraisablehook__
class Box:
    pass
def callback(_):  # a weakref callback, like importlib's module-lock one
    signal.raise_signal(signal.SIGINT)
    for _ in range(1000):  # the handler runs here, where Python cannot raise its exception
        pass
box = Box()
ref = weakref.ref(box, callback)
try:
    del box
    for _ in range(300):
        time.sleep(0.01)
except signals.Interrupted as sig:
    print("interrupted", sig.signum)
    sys.exit(130)
print("signal lost")
"""


@pytest.mark.parametrize("hook", ["mixvi", "default-hook"])
def test_a_signal_inside_a_weakref_callback_is_not_lost(hook):
    """A SIGINT whose handler runs inside a weakref callback (a Ctrl-C during the start-up
    imports lands in importlib's module-lock callback), where Python prints "Exception
    ignored" and drops the exception, is raised again in ordinary code: exit 130, no
    traceback. With Python's own unraisable hook (the mutation) the signal is lost."""
    run = subprocess.run(
        [sys.executable, "-c", IN_CALLBACK, hook], capture_output=True, text=True, timeout=60
    )
    if hook == "mixvi":
        assert run.returncode == 130 and "interrupted 2" in run.stdout, run
        assert "Traceback" not in run.stderr and "Exception ignored" not in run.stderr, run
    else:
        assert "signal lost" in run.stdout and "Exception ignored" in run.stderr, run
