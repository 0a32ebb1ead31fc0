"""Results kept on the GPU (``device='cuda'``, glvox/gpu/cuda.py): every GL surface and
solid method hands its packed grid to the device sink instead of host memory, the
result reads it back only when host data is asked for, and everything the sink
cannot take is refused in one line before any work.

Without CUDA (this suite's llvmpipe) the sink is a loopback: :class:`LoopbackSink`
keeps to :class:`glvox.gpu.cuda.CudaSink`'s contract (the grid's GL buffer, the
byte range and where it lands in a zeroed grid) but copies into host memory with
glGetBufferSubData.  So these tests check what glvox does around the copy.
CudaSink's own copy code runs on a stand-in for cuda.core (the ``Fake*`` classes:
its API as glvox calls it, host memory for device memory).  The CUDA copy itself
(interop, DLPack on the GPU) is checked only by
``test_cuda_words_equal_the_host_words``, which runs where CUDA sees the GL
context's GPU.
"""

from __future__ import annotations

import contextlib
import ctypes
import threading

import numpy as np
import pytest

import glvox
import glvox.methods
from glvox.errors import CapabilityError, GlvoxError, LimitError, MethodError
from glvox.gpu import buffers, cuda, readback
from glvox.methods import method_infos, run_method
from glvox.results import DeviceWords
from glvox.study import selftest

#: Every GL method whose result is a packed grid.
GRID_METHODS = [i.name for i in method_infos() if i.uses_gl and i.kind in ("surface", "solid")]

N = 24


class LoopbackWords(DeviceWords):
    """Words 'on the device', in a host array; counts its read-backs."""

    def __init__(self, arr: np.ndarray):
        self.arr = arr
        self.shape = arr.shape
        self.reads = 0

    def to_host(self) -> np.ndarray:
        self.reads += 1
        return self.arr.copy()

    def __dlpack__(self, **kwargs):
        return self.arr.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self.arr.__dlpack_device__()


class LoopbackSink(cuda.CudaSink):
    """CudaSink's checks and contract, host memory instead of CUDA's."""

    made: list["LoopbackSink"] = []

    def __init__(self):
        self.copies: list[tuple[int, int, int, tuple]] = []
        self.uploads = 0
        LoopbackSink.made.append(self)

    def open_device(self, ctx) -> None:
        pass

    def grid_words(self, ctx, buf, offset, nbytes, at, shape):
        self.copies.append((offset, nbytes, at, tuple(shape)))
        out = np.zeros(int(np.prod(shape)) * 4, dtype=np.uint8)
        if nbytes:
            buf.read_into(out[at:at + nbytes], size=nbytes, offset=offset)
        return LoopbackWords(out.view("<u4").reshape(shape))

    def upload(self, words):
        self.uploads += 1
        return LoopbackWords(np.array(words, dtype="<u4"))


@pytest.fixture
def loopback(monkeypatch):
    LoopbackSink.made.clear()
    monkeypatch.setattr(glvox.methods, "CudaSink", LoopbackSink)
    monkeypatch.setattr(cuda, "_MISSING", None)  # the package check passes, whatever is installed
    return LoopbackSink.made


@pytest.fixture(scope="module")
def torus():
    return glvox.load_mesh("gen:torus")


@pytest.mark.parametrize("name", GRID_METHODS)
def test_every_grid_method_hands_its_grid_to_the_sink(gl_context, loopback, torus, name):
    """One copy of the whole grid into the sink (none through host memory), the host
    run's words when read back, and no read-back before host data is asked for."""
    spec = glvox.grid_for(torus, N)
    want = run_method(name, torus, spec)
    got = run_method(name, torus, spec, device="cuda")
    (sink,) = loopback
    assert got.run.stats["device"] == "cuda" and got.run.stats["device_path"] == "gpu"
    assert sink.uploads == 0 and len(sink.copies) >= 1
    offset, nbytes, at, shape = sink.copies[-1]
    assert shape == (spec.dims[2], spec.dims[1], spec.words_per_row) and 0 <= at and at + nbytes <= spec.n_words * 4
    words = got.device_words
    assert isinstance(words, LoopbackWords) and words.reads == 0  # counted on the GPU, or not counted
    np.testing.assert_array_equal(got.words(), want.words())
    assert words.reads == 1
    assert got.count == want.count > 0
    got.dense()
    assert words.reads == 1  # read back once


def test_an_uncounted_grid_stays_on_the_device_until_counted(gl_context, loopback, torus):
    """scanline counts nothing on the GPU: its device result has no count in its stats
    (counting would read the grid back), and counting reads it back once."""
    spec = glvox.grid_for(torus, N)
    got = run_method("scanline-ilv", torus, spec, device="cuda")
    assert got.counted_on == "cpu" and "voxels" not in got.run.stats
    assert got.device_words.reads == 0
    assert got.count == run_method("scanline-ilv", torus, spec).count
    assert got.device_words.reads == 1


@pytest.mark.parametrize("name", ["ss-conservative", "passalis-stencil"])
def test_a_grid_that_missed_the_sink_is_uploaded(gl_context, loopback, torus, monkeypatch, name):
    """A method whose grid did not reach the sink still gives a device result, uploaded
    from its host words, with its extra masks, and says so."""
    monkeypatch.setattr(buffers, "active_sink", lambda: None)
    spec = glvox.grid_for(torus, N)
    got = run_method(name, torus, spec, device="cuda")
    (sink,) = loopback
    assert sink.copies == [] and sink.uploads == 1
    assert got.run.stats["device_path"] == "host"
    want = run_method(name, torus, spec)
    np.testing.assert_array_equal(got.words(), want.words())
    assert set(got.extras) == set(want.extras) == ({"unclassifiable"} if name == "passalis-stencil" else set())


def test_a_sink_is_seen_only_by_its_own_thread():
    """GL contexts are current per thread: a device_sink block routes that thread's reads alone."""
    seen = []
    with readback.device_sink("mine"):
        worker = threading.Thread(target=lambda: seen.append(readback.active_sink()))
        worker.start()
        worker.join()
        assert readback.active_sink() == "mine"
        with readback.device_sink("inner"):
            assert readback.active_sink() == "inner"
        assert readback.active_sink() == "mine"
    assert seen == [None] and readback.active_sink() is None


def test_the_host_default_is_unchanged(gl_context, torus):
    got = glvox.voxelize(torus, N, device="host")
    assert got.device_words is None and "device" not in got.run.stats


def _no_work(monkeypatch):
    """Fail the test if any method runs."""
    def refuse(*args, **kwargs):
        raise AssertionError("work started before the refusal")
    for info in method_infos():
        monkeypatch.setattr(glvox.methods.get_method(info.name), "run", refuse)


@pytest.mark.parametrize("method, kwargs, error, words", [
    ("reference-solid", {}, MethodError, "a CPU method"),
    ("ss-octree", {}, MethodError, "its result is 'sparse'"),
    ("ss-conservative", {"attributes": "triangle"}, MethodError, "no per-voxel attributes"),
])
def test_what_cannot_stay_on_the_device_is_refused_first(gl_context, loopback, torus, monkeypatch,
                                                         method, kwargs, error, words):
    _no_work(monkeypatch)
    with pytest.raises(error, match=words) as exc:
        glvox.voxelize(torus, N, method=method, device="cuda", **kwargs)
    assert "\n" not in str(exc.value)


def test_a_slabbed_grid_is_refused_first(gl_context, loopback, torus, monkeypatch):
    """A grid over the storage-block limit is voxelized in z slabs, read slab by slab
    into host memory: refused before any work."""
    spec = glvox.grid_for(torus, N)
    limits = gl_context.limits()
    monkeypatch.setattr(gl_context, "limits", lambda: {**limits, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE":
                                                       spec.n_words * 4 // 2})
    _no_work(monkeypatch)
    with pytest.raises(LimitError, match="z slabs"):
        run_method("ss-conservative", torus, spec, ctx=gl_context, device="cuda")


def test_device_names_and_the_extra_are_checked_before_loading(monkeypatch, tmp_path):
    """A bad device name, and 'cuda' without cuda-core, fail before the mesh is read
    (the path does not exist)."""
    missing = tmp_path / "nothing.ply"
    with pytest.raises(GlvoxError, match="device must be one of host, cuda, got 'gpu'"):
        glvox.voxelize(missing, N, device="gpu")
    monkeypatch.setattr(cuda, "_MISSING", ImportError("No module named 'cuda'"))
    with pytest.raises(CapabilityError, match=r"pip install 'glvox\[cuda\]'"):
        glvox.voxelize(missing, N, device="cuda")


def _cuda_words_or_skip(gl_context):
    """A CudaSink open on the GL context's GPU, or skip saying why."""
    try:
        sink = cuda.CudaSink()
        sink.open_device(gl_context)
    except CapabilityError as exc:
        pytest.skip(f"no CUDA for this GL context: {exc}")
    return sink


def test_without_cuda_the_refusal_is_one_line_before_any_work(gl_context, torus, monkeypatch):
    """Where CUDA does not see the GL context's GPU (llvmpipe; a driver without CUDA),
    'cuda' is refused naming the way out, before any method runs."""
    try:
        cuda.check_device("cuda")
    except CapabilityError:
        pytest.skip("cuda-core is not installed")
    try:
        cuda.CudaSink().open_device(gl_context)
    except CapabilityError:
        pass
    else:
        pytest.skip("CUDA sees this GL context")
    _no_work(monkeypatch)
    with pytest.raises(CapabilityError, match="use device='host'") as exc:
        glvox.voxelize(torus, N, ctx=gl_context, device="cuda")
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("name", ["ss-conservative", "ss-solid", "eisemann-solid", "scanline-ilv", "vote-solid"])
def test_cuda_words_equal_the_host_words(gl_context, torus, name):
    """On a GPU that CUDA sees: the words in CUDA memory (read back through cuda.core
    and through DLPack's device tuple) are the host run's, for a whole grid and for a
    grid read from its mesh's slices only (ss-solid, vote-solid)."""
    _cuda_words_or_skip(gl_context)
    spec = glvox.grid_for(torus, 64)
    got = run_method(name, torus, spec, ctx=gl_context, device="cuda")
    want = run_method(name, torus, spec, ctx=gl_context)
    assert got.run.stats["device_path"] == "gpu"
    kind, _ = got.device_words.__dlpack_device__()
    assert kind == 2  # kDLCUDA
    np.testing.assert_array_equal(got.device_words.to_host(), want.words())
    assert got.count == want.count > 0


class CorruptingSink(LoopbackSink):
    """A copy that flips the 32 bits of the grid's last word."""

    def grid_words(self, ctx, buf, offset, nbytes, at, shape):
        words = super().grid_words(ctx, buf, offset, nbytes, at, shape)
        words.arr.reshape(-1)[-1] ^= 0xFFFFFFFF
        return words


@pytest.mark.parametrize("sink, status", [(LoopbackSink, "ok"), (CorruptingSink, "mismatch")])
def test_the_selftest_checks_device_words(gl_context, loopback, monkeypatch, sink, status):
    """``glvox selftest``'s readback row compares device words with host words where
    the sink opens (here the loopback stands in for CUDA), and fails a bad copy."""
    monkeypatch.setattr(glvox.methods, "CudaSink", sink)
    monkeypatch.setattr(selftest, "CudaSink", sink)
    row = selftest.readback_row(gl_context)
    assert row.cases == 4 and row.status == status
    assert row.detail[-1].startswith("device='cuda': the same words" if status == "ok" else
                                     "device='cuda': 64 voxels differ in CUDA memory")  # 32 bits flipped, twice
    assert (row.mismatches == 0) == (status == "ok")


# -- CudaSink itself, on a stand-in for cuda.core ------------------------------------
# cuda.core's objects as glvox uses them (its 1.2 API), with host memory for device
# memory: a mapped GL buffer is read into host memory on map(), pointers are addresses,
# copies are memmoves.  They run CudaSink's own code (pointer arithmetic, the zeroed
# grid, map / unmap / unregister order) against real GL buffers; they prove nothing
# about the driver.

_GL_BUFFER_SIZE = 0x8764


class FakeStream:
    def __init__(self):
        self.syncs = 0

    def sync(self):
        self.syncs += 1


class FakeBuffer:
    def __init__(self, address: int, size: int, owner=None):
        self.handle, self.size, self.owner = int(address), int(size), owner

    @classmethod
    def from_handle(cls, ptr, size, mr=None, owner=None, *, stream=None):
        return cls(ptr, size, owner)

    def copy_from(self, src, *, stream):
        assert src.size == self.size
        ctypes.memmove(self.handle, src.handle, self.size)

    def copy_to(self, dst, *, stream):
        assert dst.size == self.size
        ctypes.memmove(dst.handle, self.handle, self.size)

    def fill(self, value, *, stream):
        ctypes.memset(self.handle, value, self.size)


class FakeDevice:
    def __init__(self, device_id=None):
        self.device_id = 0 if device_id is None else device_id

    def set_current(self):
        pass

    def create_stream(self):
        return FakeStream()

    def allocate(self, size, *, stream):
        arr = np.full(size, 0xAB, dtype=np.uint8)  # garbage, as cudaMalloc's may be
        return FakeBuffer(arr.ctypes.data, size, owner=arr)


class FakeResource:
    live: list["FakeResource"] = []
    ctx = None

    def __init__(self, name):
        self.name, self.mapped = name, False

    @classmethod
    def from_gl_buffer(cls, gl_buffer, *, flags=None, stream=None):
        assert flags == "read_only"
        r = cls(int(gl_buffer))
        cls.live.append(r)
        return r

    @contextlib.contextmanager
    def map(self, *, stream):
        load = FakeResource.ctx.raw._loader
        size = ctypes.c_int(0)
        ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))(
            load("glGetNamedBufferParameteriv"))(self.name, _GL_BUFFER_SIZE, ctypes.byref(size))
        host = np.empty(size.value, dtype=np.uint8)
        ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_void_p)(
            load("glGetNamedBufferSubData"))(self.name, 0, size.value, host.ctypes.data)
        self.mapped = True
        try:
            yield FakeBuffer(host.ctypes.data, host.size, owner=host)
        finally:
            self.mapped = False

    def close(self):
        assert not self.mapped, "unregistered while mapped"
        FakeResource.live.remove(self)


class FakeView:
    @classmethod
    def from_buffer(cls, buffer, shape, strides=None, *, itemsize=None, dtype=None, is_readonly=False):
        v = cls()
        v.buffer = buffer
        raw = (ctypes.c_uint8 * buffer.size).from_address(buffer.handle)
        v.arr = np.frombuffer(raw, dtype=np.uint8).view(dtype).reshape(shape)
        return v

    def __dlpack__(self, **kwargs):
        return self.arr.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self.arr.__dlpack_device__()


@pytest.fixture
def fake_cuda(gl_context, monkeypatch):
    for name, fake in (("Buffer", FakeBuffer), ("Device", FakeDevice), ("GraphicsResource", FakeResource),
                       ("StridedMemoryView", FakeView)):
        monkeypatch.setattr(cuda, name, fake, raising=False)
    monkeypatch.setattr(cuda, "_MISSING", None)
    monkeypatch.setattr(gl_context, "cuda_ordinal", lambda: 0)
    FakeResource.live.clear()
    FakeResource.ctx = gl_context
    kept = gl_context.caches.pop("cuda", None)  # the device CudaSink opened for this context
    yield FakeResource.live
    gl_context.caches.pop("cuda", None)
    if kept is not None:
        gl_context.caches["cuda"] = kept


@pytest.mark.parametrize("name", GRID_METHODS)
def test_the_cuda_sink_copies_each_grid_whole(fake_cuda, gl_context, torus, name):
    """CudaSink's copy on the stand-in: the host run's words, the slices a method did
    not read zeroed (the allocation starts as garbage), DLPack giving the same words,
    and every registration unmapped and closed."""
    spec = glvox.grid_for(torus, N)
    got = run_method(name, torus, spec, ctx=gl_context, device="cuda")
    want = run_method(name, torus, spec, ctx=gl_context)
    assert isinstance(got.device_words, cuda.CudaWords) and got.run.stats["device_path"] == "gpu"
    np.testing.assert_array_equal(np.from_dlpack(got.device_words), want.words())
    np.testing.assert_array_equal(got.device_words.to_host(), want.words())
    assert fake_cuda == []


def test_the_cuda_sink_uploads_a_grid_that_missed_it(fake_cuda, gl_context, torus, monkeypatch):
    monkeypatch.setattr(buffers, "active_sink", lambda: None)
    spec = glvox.grid_for(torus, N)
    got = run_method("ss-solid", torus, spec, ctx=gl_context, device="cuda")
    assert got.run.stats["device_path"] == "host"
    np.testing.assert_array_equal(got.device_words.to_host(), run_method("ss-solid", torus, spec).words())


def test_the_cuda_device_is_opened_once_per_context(fake_cuda, gl_context, torus, monkeypatch):
    """Finding the GL context's CUDA device (EGL or cuGLGetDevices) and making a stream is
    setup, not per-call work: a second call reuses them."""
    opened = []
    monkeypatch.setattr(gl_context, "cuda_ordinal", lambda: opened.append(1) or 0)
    spec = glvox.grid_for(torus, N)
    first = run_method("ss-conservative", torus, spec, ctx=gl_context, device="cuda")
    second = run_method("ss-conservative", torus, spec, ctx=gl_context, device="cuda")
    assert opened == [1] and first.device_words.stream is second.device_words.stream


def test_a_failing_cuda_copy_is_one_line(fake_cuda, gl_context, torus, monkeypatch):
    """A driver error in the interop (here the registration) reaches the user as one
    CapabilityError line naming the step and the way out, not a traceback of cuda.core's."""
    def refuse(*args, **kwargs):
        raise RuntimeError("CUDA_ERROR_INVALID_GRAPHICS_CONTEXT")
    monkeypatch.setattr(FakeResource, "from_gl_buffer", refuse)
    with pytest.raises(CapabilityError, match="interop.*CUDA_ERROR_INVALID_GRAPHICS_CONTEXT.*use device='host'") as exc:
        glvox.voxelize(torus, N, ctx=gl_context, device="cuda")
    assert "\n" not in str(exc.value)
