"""The command line's malloc tuning: freed pages are reused instead of mapped and zero-filled afresh."""

import ctypes
import ctypes.util
import subprocess
import sys
import textwrap

import pytest

import sensorplan.cli
from sensorplan import _allocator


def _has_mallinfo2():
    name = ctypes.util.find_library("c") if sys.platform.startswith("linux") else None
    return name is not None and hasattr(ctypes.CDLL(name), "mallinfo2")


GLIBC = _has_mallinfo2()  # glibc >= 2.33

# a 64 MiB array allocated, written and freed; prints the free bytes malloc keeps in its heap afterwards
# (glibc's mallinfo2: arena, ordblks, smblks, hblks, hblkhd, usmblks, fsmblks, uordblks, fordblks, keepcost)
KEPT = textwrap.dedent("""
    import ctypes, ctypes.util, sys
    import numpy as np
    from sensorplan._allocator import keep_freed_memory
    class Info(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                          "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    libc.mallinfo2.restype = Info
    if sys.argv[1] == "tuned":
        assert keep_freed_memory()
    a = np.ones(8 * 2**20)
    del a
    print(libc.mallinfo2().fordblks)
""")


def _kept(mode):
    out = subprocess.run([sys.executable, "-c", KEPT, mode], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


@pytest.mark.skipif(not GLIBC, reason="glibc >= 2.33 only (mallopt, mallinfo2)")
def test_freed_pages_are_kept_for_reuse():
    # untuned, a 64 MiB array gets its own mapping, handed back to the system on free (the next one is mapped
    # and zero-filled afresh); tuned, it comes from the heap, which keeps the freed pages
    size = 64 * 2**20
    assert _kept("plain") < size // 4
    assert _kept("tuned") >= size


def test_without_a_c_library_nothing_changes(monkeypatch):
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    assert _allocator.keep_freed_memory() is False


def test_the_command_line_tunes_its_process(monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(sensorplan.cli, "keep_freed_memory", lambda: calls.append(1) or True)
    assert sensorplan.cli.main([]) == 0
    assert calls == [1]
    assert "usage" in capsys.readouterr().out
