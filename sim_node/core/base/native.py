"""
MuJoCo's own library called through ctypes, which lets the GIL go while it works.

For the calls the bindings make holding the GIL that last long enough to hold every other
thread of the process up. MuJoCo's Python bindings hold the GIL in ``mjr_makeContext`` (266 ms
for the default scene with robosuite's GR1, Mesa) and in ``MjSpec.delete`` (26 ms for TIAGo's
frame): meanwhile the stepping loop and the /clock publisher stood still
(``make bench-spawn-clock``). ctypes releases the GIL around a foreign call, so the same
functions called through it leave the other threads running. The library is the bindings' own
(loaded once per process, so one set of globals); each wrapper here says what it falls back to
when the bindings give no address.
"""

import ctypes
import os
from typing import Optional

import mujoco

_LIBRARY: list = []


def library() -> ctypes.CDLL:
    """Return MuJoCo's library, the bindings' own, with the prototypes used here."""
    if not _LIBRARY:
        folder = os.path.dirname(mujoco.__file__)
        name = next(n for n in sorted(os.listdir(folder)) if n.startswith('libmujoco.so'))
        lib = ctypes.CDLL(os.path.join(folder, name))
        lib.mjr_makeContext.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int)
        lib.mjr_makeContext.restype = None
        lib.mjs_findFrame.argtypes = (ctypes.c_void_p, ctypes.c_char_p)
        lib.mjs_findFrame.restype = ctypes.c_void_p
        lib.mjs_delete.argtypes = (ctypes.c_void_p, ctypes.c_void_p)
        lib.mjs_delete.restype = ctypes.c_int
        _LIBRARY.append(lib)
    return _LIBRARY[0]


def delete_frame(spec: mujoco.MjSpec, name: str) -> bool:
    """
    Delete the frame `name` of `spec` with all attached through it, the GIL released.

    ``mjs_findFrame`` gives the frame, whose first member is its element; ``mjs_delete``
    deletes it. False (nothing done) when the spec gives no address or has no such frame: the
    caller deletes it through the bindings.
    """
    address = getattr(spec, '_address', None)
    if not address:
        return False
    lib = library()
    frame = lib.mjs_findFrame(ctypes.c_void_p(address), name.encode())
    if not frame:
        return False
    element = ctypes.c_void_p.from_address(frame).value
    return bool(element) and lib.mjs_delete(ctypes.c_void_p(address),
                                            ctypes.c_void_p(element)) == 0


def make_context(model: mujoco.MjModel) -> Optional[mujoco.MjrContext]:
    """
    Return an OpenGL context for `model` (current on this thread), made with the GIL released.

    Made into the struct an empty :class:`mujoco.MjrContext` holds, the bindings' own object
    (it frees the context when it goes). None (nothing made) when the model or that struct
    gives no address: the caller makes it through the bindings.
    """
    address = getattr(model, '_address', None)
    con = mujoco.MjrContext()
    struct = _context_address(con)
    if not address or struct is None:
        return None
    library().mjr_makeContext(ctypes.c_void_p(address), ctypes.c_void_p(struct),
                              ctypes.c_int(int(mujoco.mjtFontScale.mjFONTSCALE_100)))
    return con


def _context_address(con: mujoco.MjrContext) -> Optional[int]:
    """
    Return the address of the mjrContext `con` wraps, or None if it cannot be checked.

    The bindings give none; its ``fogRGBA`` array is a view into it and follows five floats.
    Checked by a write through the address that the bindings must read back (``fogStart``).
    """
    try:
        base = con.fogRGBA.ctypes.data - 5 * ctypes.sizeof(ctypes.c_float)
    except (AttributeError, TypeError):
        return None
    probe = ctypes.c_float.from_address(base + 3 * ctypes.sizeof(ctypes.c_float))  # fogStart
    old = probe.value
    probe.value = 1234.5
    same = con.fogStart == 1234.5
    probe.value = old
    return base if same else None
