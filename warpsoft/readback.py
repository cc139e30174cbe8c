"""What the host reads after the device ran: gathered on the device into one buffer, read in one copy.

A step's host side needs a dozen small arrays (the solver's residuals, the health flags, row
values, multipliers, mapped points). Read one by one, each costs a synchronizing transfer and
its Python overhead (tens of microseconds on CUDA: as much as a third of a small robot's
step). A :class:`Readback` copies their bytes, device to device, into one buffer at the end of
the device work (inside a captured graph, these copies are graph nodes), and the host reads that
buffer once into pinned memory and views each array in it.
"""

from __future__ import annotations

import numpy as np
import warp as wp


class Readback:
    """Args:
        arrays: name -> contiguous device array, all on ``device``; their current buffers are the
            ones copied (an array must not be reallocated afterwards).
        device: the Warp device.
    """

    def __init__(self, arrays: dict[str, wp.array], device):
        self.device = wp.get_device(device)
        # on the CPU device the arrays are host memory already: each is read in place (the
        # gather's copies and the read: 0.18 -> 0.06 ms for the Grasper's fifteen arrays)
        self._in_place = dict(arrays) if self.device.is_cpu else None
        self._sources, layout, offset = [], {}, 0
        for name, a in arrays.items():
            if not a.is_contiguous:
                raise ValueError(f"Readback: array '{name}' must be contiguous")
            nbytes = a.size * wp.types.type_size_in_bytes(a.dtype)
            scalar = getattr(a.dtype, "_wp_scalar_type_", a.dtype)
            shape = (*a.shape, *getattr(a.dtype, "_shape_", ()))
            self._sources.append((wp.array(ptr=a.ptr, dtype=wp.uint8, shape=nbytes, device=self.device), offset,
                                  nbytes))
            layout[name] = (offset, np.dtype(wp.dtype_to_numpy(scalar)), shape)
            offset += -(-nbytes // 8) * 8  # 8-byte aligned
        self.nbytes = max(offset, 8)
        self._buffer = wp.empty(self.nbytes, dtype=wp.uint8, device=self.device)
        self._host = wp.empty(self.nbytes, dtype=wp.uint8, device="cpu", pinned=self.device.is_cuda)
        raw = self._host.numpy()  # views into the host buffer, made once
        self._views = {name: np.frombuffer(raw, dtype=dt, count=int(np.prod(shape)), offset=off).reshape(shape)
                       for name, (off, dt, shape) in layout.items()}

    def gather(self) -> None:
        """Copy every array into the buffer (device to device; capturable); nothing on the CPU."""
        if self._in_place is not None:
            return
        for src, offset, nbytes in self._sources:
            wp.copy(self._buffer, src, dest_offset=offset, count=nbytes)

    def read(self) -> dict[str, np.ndarray]:
        """One transfer of the buffer; returns a copy of each array, by name, in its numpy shape
        (vector and matrix elements as trailing axes). It waits for the current stream alone,
        where the gather ran (work on other streams, such as the copies to the refactorizing
        workers, goes on beside)."""
        if self._in_place is not None:
            return {name: a.numpy().copy() for name, a in self._in_place.items()}
        stream = wp.get_stream(self.device)
        wp.copy(self._host, self._buffer, stream=stream)
        wp.synchronize_stream(stream)
        return {name: view.copy() for name, view in self._views.items()}
