"""Motion-JPEG frames put together from rows encoded before: a simulated run's video
costs its encoder only the rows of a frame it has not seen.

A JPEG whose restart interval is one row of MCUs (``DRI``) codes every row on its own:
the DC prediction restarts at each row, and each row ends byte-aligned, followed by a
restart marker (``RST0``-``RST7`` in turn). With the standard Huffman tables (libjpeg's
default, which OpenCV keeps) a row's bytes depend on that row's pixels only. So a row
whose pixels are known to be those of a row encoded before (same ``key``) is copied, and
only the others are encoded: a batch's new rows stacked into one image, whose rows are
cut at their restart markers.

The result is byte for byte the file libjpeg writes for the whole frame with that
restart interval (``tests/recording/test_jpeg_rows.py`` checks it against ``cv2.imencode``), and it
decodes to the same pixels as a frame encoded without restarts: restarts change how the
coefficients are framed, not the coefficients. The cost: 2 bytes a row.

A simulated camera's frame is mostly flat fill plus noise read from a fixed noise frame
at an offset that is a multiple of the MCU's size (``labrig.sim.camera``): its rows
repeat across frames, except those the markers cross. At 640x360 grey that makes a
frame ~0.2 ms of the encoder's CPU (keys, drawing, encoding and muxing) instead of
~0.5 ms to draw and encode it whole.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Hashable, Sequence

import cv2
import numpy as np

from labrig.arrays import runs_of_true

# between two rows' bytes: FF D0-D7 (inside the entropy-coded bytes an FF is always
# followed by 00, so this is a marker wherever it occurs)
_RESTART = re.compile(rb"\xff[\xd0-\xd7]")
_SOF0, _SOS, _EOI = b"\xff\xc0", b"\xff\xda", b"\xff\xd9"
_RST = [bytes((0xFF, 0xD0 + k)) for k in range(8)]
# a JPEG is at most 65535 pixels high: rows encoded together are stacked up to this
_MAX_JPEG_ROWS_PX = 60_000


class RowJpeg:
    """JPEG frames of one size, ``quality`` (OpenCV's 0-100), grey or BGR colour, with a
    restart at every row of MCUs, assembled from cached rows (``frames``). Keeps up to
    ``cache_rows`` rows (about 200 bytes each at 640 pixels wide, grey)."""

    def __init__(
        self, width: int, height: int, colour: bool, quality: int, cache_rows: int = 50_000
    ) -> None:
        self.width, self.height, self.colour = int(width), int(height), bool(colour)
        self._cache: dict[Hashable, bytes] = {}
        self._cache_rows = int(cache_rows)
        blank = np.zeros((self.height, self.width, 3) if colour else (self.height, self.width),
                         dtype=np.uint8)  # fmt: skip
        # the MCU's size is libjpeg's choice (4:2:0 for colour): read from the header
        first = cv2.imencode(".jpg", blank, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])[1].tobytes()
        h_max, v_max = _max_sampling(first)
        self.row_px = 8 * v_max
        self.n_rows = math.ceil(self.height / self.row_px)
        per_row = math.ceil(self.width / (8 * h_max))  # MCUs in a row: the restart interval
        self._params = [
            cv2.IMWRITE_JPEG_QUALITY, int(quality), cv2.IMWRITE_JPEG_RST_INTERVAL, per_row
        ]  # fmt: skip
        self._header, rows = self._split(self.encode(blank))
        if len(rows) != self.n_rows:
            raise RuntimeError(f"JPEG rows: {len(rows)} rows in a frame, not {self.n_rows}")
        self.n_encoded_rows = 0  # rows encoded rather than copied (what the tests count)

    def encode(self, image: np.ndarray) -> bytes:
        """The whole frame, with restarts at every row (what ``frames`` assembles)."""
        ok, data = cv2.imencode(".jpg", image, self._params)
        if not ok:
            raise OSError("OpenCV could not encode a frame as JPEG")
        return data.tobytes()

    def frames(
        self,
        keys: Sequence[Sequence[Hashable | None]],
        render: Callable[[list[tuple[int, int, int]]], Sequence[np.ndarray]],
    ) -> list[bytes]:
        """A batch of frames' JPEGs. Row i of frame f is copied when ``keys[f][i]`` was
        seen before (in this batch or an earlier one); the others are drawn by
        ``render(spans)``: for each span (f, y0, y1), frame f's pixel rows [y0, y1),
        full width. A batch draws its new rows together and encodes them together: a
        simulated frame's few new rows would cost mostly numpy's and OpenCV's per-call
        overhead one by one. A None key is a row never reused (a marker crosses it)."""
        if len(self._cache) > self._cache_rows:
            self._cache.clear()  # a long run's old rows: they come back rarely
        cache, pending = self._cache, set()
        rows, spans = [], []
        for f, frame_keys in enumerate(keys):
            if len(frame_keys) != self.n_rows:
                raise ValueError(f"JPEG rows: {len(frame_keys)} keys for {self.n_rows} rows")
            frame_rows = [None if key is None else cache.get(key) for key in frame_keys]
            fresh = []  # rows to encode: unknown ones, each key once
            for row, key in zip(frame_rows, frame_keys, strict=True):
                fresh.append(row is None and (key is None or key not in pending))
                if row is None and key is not None:
                    pending.add(key)
            spans += [(f, int(first) * self.row_px, min((int(last) + 1) * self.row_px, self.height))
                      for first, last in runs_of_true(fresh)]  # fmt: skip
            rows.append(frame_rows)
        pixels = render(spans) if spans else []
        for (f, y0, _), span_rows in zip(spans, self._encode_spans(pixels), strict=True):
            for i, row in enumerate(span_rows, y0 // self.row_px):
                rows[f][i] = row
                if keys[f][i] is not None:
                    cache[keys[f][i]] = row
        return [
            self._assemble([cache[key] if row is None else row
                            for row, key in zip(frame_rows, frame_keys, strict=True)])
            for frame_rows, frame_keys in zip(rows, keys, strict=True)
        ]  # fmt: skip

    def _encode_spans(self, pixels: Sequence[np.ndarray]) -> list[list[bytes]]:
        """Each span's rows' bytes. Spans of whole rows are stacked into one image and
        encoded at once (its rows are coded apart all the same); a span ending in the
        frame's short last row is encoded alone, padded as the whole frame is."""
        encoded: list[list[bytes] | None] = [None] * len(pixels)
        whole = []
        for j, span in enumerate(pixels):
            if span.shape[0] % self.row_px == 0:
                whole.append(j)
            else:
                encoded[j] = self._rows_of(span)
        for chunk in _chunks(whole, [pixels[j].shape[0] for j in whole], _MAX_JPEG_ROWS_PX):
            stacked = self._rows_of(np.concatenate([pixels[j] for j in chunk]))
            for j in chunk:
                n = pixels[j].shape[0] // self.row_px
                encoded[j], stacked = stacked[:n], stacked[n:]
        return encoded

    def _rows_of(self, pixels: np.ndarray) -> list[bytes]:
        _, rows = self._split(self.encode(pixels))
        if len(rows) != math.ceil(pixels.shape[0] / self.row_px):
            raise RuntimeError(f"JPEG rows: {len(rows)} rows from {pixels.shape[0]} pixel rows")
        self.n_encoded_rows += len(rows)
        return rows

    def _assemble(self, rows: list[bytes]) -> bytes:
        out = [self._header]
        for i, row in enumerate(rows):
            out.append(row)
            out.append(_RST[i % 8] if i + 1 < self.n_rows else _EOI)
        return b"".join(out)

    @staticmethod
    def _split(data: bytes) -> tuple[bytes, list[bytes]]:
        """(everything up to the scan's data, [each row's bytes])."""
        sos = data.index(_SOS)
        start = sos + 2 + int.from_bytes(data[sos + 2 : sos + 4], "big")
        if not data.endswith(_EOI):
            raise RuntimeError("JPEG rows: the encoded frame does not end with EOI")
        return data[:start], _RESTART.split(data[start:-2])


def _max_sampling(data: bytes) -> tuple[int, int]:
    """The largest horizontal and vertical sampling factors in a baseline JPEG's frame
    header: an MCU is 8 times these in pixels."""
    sof = data.index(_SOF0)
    n_components = data[sof + 9]
    factors = [data[sof + 11 + 3 * c] for c in range(n_components)]
    return max(f >> 4 for f in factors), max(f & 0x0F for f in factors)


def _chunks(items: list, sizes: list[int], limit: int) -> list[list]:
    """``items`` in order, in chunks whose sizes add up to at most ``limit`` each."""
    chunks, chunk, total = [], [], 0
    for item, size in zip(items, sizes, strict=True):
        if chunk and total + size > limit:
            chunks.append(chunk)
            chunk, total = [], 0
        chunk.append(item)
        total += size
    return [*chunks, chunk] if chunk else chunks
