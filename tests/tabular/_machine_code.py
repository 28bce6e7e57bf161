"""The machine code numba runs for a compiled function, read without compiling it again.

A function with ``cache=True`` is either compiled in this process or loaded from numba's
on-disk cache; in both cases the object code that runs is at hand: the compiled
library's own object, or the object stored in the cache entry the function was loaded
from. Reading it costs nothing, where compiling a large episode loop afresh to inspect
its LLVM IR took a minute on a 2-core machine with a cold cache.
"""

from __future__ import annotations

from typing import Any


def object_code(dispatcher: Any, sig: Any) -> bytes:
    """The object code of ``dispatcher``'s overload for ``sig`` (compiled or loaded)."""
    library = dispatcher.overloads[sig].library
    try:
        return bytes(library.serialize_using_object_code()[2][0])
    except RuntimeError:  # loaded from the cache: numba keeps no object for it
        cache = dispatcher._cache
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        data = cache._cache_file.load(key)
        assert data is not None, f"{dispatcher.__name__} has no cache entry for {sig}"
        name, kind, (obj, _bitcode) = data[0]
        assert kind == "object", kind
        return bytes(obj)


def reference_count_symbols(obj: bytes) -> set[str]:
    """The names of numba's reference-counting runtime functions the code refers to.

    A compiled function that counts references calls ``NRT_incref`` / ``NRT_decref``
    (and ``NRT_MemInfo_call_dtor`` when a count reaches zero); their names stay in the
    object's symbol table even where the increments themselves were inlined.
    """
    names = ("NRT_incref", "NRT_decref", "NRT_MemInfo_call_dtor")
    return {n for n in names if n.encode() in obj}
