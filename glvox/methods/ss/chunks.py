"""The two dispatches of a per-triangle kernel whose work comes in chunks.

``first`` runs one invocation per triangle: it does the triangle's first chunk
and appends the triangles with more to a list (storage block ``Big``:
``big_count``, ``big_max_chunks`` = the most chunks after the first,
``big_list``); ``ss/solid_big_args.comp`` sizes the indirect dispatch of
``rest``, which runs the listed triangles' remaining chunks.  A chunk holds
thousands of work units, so the list is nearly empty and the triangles are set
up once, without a pass that only counts their chunks.  ``ss/solid.comp``
(``FIRST``), ``gwn/events.comp`` and ``ss/surface.comp`` (``SS_FIRST``) run this way.
"""

from __future__ import annotations

from ...gl.shaders import compute_program
from ...gpu.dispatch import barrier, bind, dispatch_1d, set_uniforms

#: The shader that writes ``rest``'s indirect arguments.
BIG_ARGS = "ss/solid_big_args.comp"


def chunked_passes(ctx, progs, n: int, max_groups: int, blocks, big, args, local_size: int) -> None:
    """Run ``progs = (first, rest)`` over ``n`` triangles.

    ``blocks``: the kernels' buffers by storage block name; ``big``: the list
    (``Big``), its first two words cleared by the caller; ``args``: three words
    of indirect arguments.  Both kernels have ``local_size_x`` = ``local_size``.
    """
    first, rest = progs
    big_args = compute_program(ctx, BIG_ARGS)
    set_uniforms(big_args, {"u_local_size": local_size, "u_max_groups": max_groups})
    bind(first, **blocks, Big=big)
    dispatch_1d(ctx, first, n, local_size)
    barrier(ctx)
    bind(big_args, Big=big, Args=args)
    big_args.run(1, 1, 1)
    barrier(ctx)
    bind(rest, **blocks, Big=big)
    rest.run_indirect(args)
    barrier(ctx)
