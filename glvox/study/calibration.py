"""A fixed GL workload timed beside the contenders: how busy the GL device was.

Other work on a shared machine slows llvmpipe's threads far more than it
slows a single-threaded peer, so the peers alone misjudge how busy the GL
device was.  ``glvox bench`` times this workload in every round of every
cell (the calibration contender, :data:`glvox.study.plan.CALIBRATION_KEY`);
the ratio of its best time now to its best time in the baseline is the
machine factor of the regression check (:mod:`glvox.study.regression`).
"""

from __future__ import annotations

from glvox.gl.shaders import compute_program
from glvox.gpu.dispatch import bind

#: ``shaders/testing/busy.comp`` (a fixed chain of sines per invocation) over
#: this many work groups of 64, this many iterations each: well under a
#: contender's loop budget (the time on one machine is in the bench's tables).
CALIBRATION_GROUPS, CALIBRATION_ITERATIONS = 128, 1000


class Calibration:
    """The workload's program and output buffer on ``ctx`` (a GLContext)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.prog = compute_program(ctx, "testing/busy.comp")
        self.buf = ctx.mgl.buffer(reserve=CALIBRATION_GROUPS * 64 * 4)

    def run(self) -> None:
        """One dispatch, waited for."""
        self.ctx.make_current()
        bind(self.prog, Out=self.buf)
        self.prog["u_iterations"].value = CALIBRATION_ITERATIONS
        self.prog.run(CALIBRATION_GROUPS)
        self.ctx.mgl.finish()

    def release(self) -> None:
        self.buf.release()
