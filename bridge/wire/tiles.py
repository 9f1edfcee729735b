"""Images and point clouds cut into standalone tiles of one datagram each.

Theory of operation
-------------------
The paper's UDP bridge splits a point cloud or an image into sub-regions, each
a valid small cloud or image in one 1500-byte datagram, so a lost datagram
costs one region instead of the whole frame.  Here both are a *raster*: an
``H x W`` grid of cells (a pixel, or an organized cloud's point as
``point_step`` bytes; an unorganized cloud is ``1 x N``).  :func:`split`
covers the raster with rectangles whose encoding fits :data:`BODY_BUDGET`:
it guesses a tile size from the whole frame's compressed size, then halves
any tile that still does not fit.

Each tile body repeats what is needed to use it alone -- the raster header
(size, cell type, codec, how to fill what is missing) and the message's
metadata (a compact Bottle: stamp, frame, encoding, fields...) -- followed by
its rectangle and data.  Codecs: JPEG for 8-bit images (the JPEG header,
600 bytes that only depend on quality and channels, is rebuilt by the
receiver instead of sent), PNG for 16-bit images, zlib for float images and
clouds.

:class:`Canvas` pastes whatever tiles arrived into a frame filled with blanks
(zeros) or NaN (float images, the float fields of a cloud) and gives its
:class:`Arrival`: the fraction of cells it received and :func:`regions`
covering exactly the cells no tile brought.  Blanks are only a filling: a black
sky or a point without depth looks the same, so whoever must tell loss from
content asks the canvas (the pilot bridge publishes its arrival beside the frame),
never the pixels.

Hostile input
-------------
A tile comes off the network, so :func:`decode_tile` checks every header
field before anything is allocated or decoded, and refuses with
:class:`BridgeProtocolError` naming the field:

* cell type, fill and codec must be known and agree with each other: NaN fill
  only for float cells, NaN-at-offsets only for byte cells (a cloud point),
  JPEG only for 8-bit cells of 1 or 3 channels, PNG for 8/16-bit cells of 1,
  3 or 4 channels, quality 0..100;
* limits: at most :data:`MAX_CELLS` cells, 4096 channels, 64 NaN offsets and
  :data:`MAX_RASTER_BYTES` bytes for the whole raster (the canvas a tile
  makes the receiver allocate), and the tile inside its raster;
* an embedded PNG or full JPEG must declare the tile's own size before the
  image decoder sees it, so a tiny datagram cannot make OpenCV allocate a
  huge image, and no other image format reaches OpenCV.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from functools import lru_cache
from typing import Dict, Iterable, List, Optional, Sequence, Set, Tuple

import numpy as np

from bridge.errors import BridgeProtocolError, BridgeUsageError, NeedMoreData
from bridge.wire.datagrams import BODY_BUDGET
from bridge.wire.varint import Buffer, get_varint, put_varint, take

JPEG, JPEG_FULL, PNG, ZLIB = 1, 2, 3, 4
CODEC_NAMES = {"jpeg": JPEG, "png": PNG, "zlib": ZLIB}
FILL_ZERO, FILL_NAN, FILL_NAN_AT = 0, 1, 2
DTYPES = (np.uint8, np.uint16, np.int16, np.float32, np.float64, np.int8, np.int32, np.uint32)
_DTYPE_CODE = {np.dtype(t).str: code for code, t in enumerate(DTYPES)}
#: Largest raster (cells) and canvas (bytes) a peer may make the receiver allocate:
#: a 2048 x 1088 cloud of 32-byte points is 71 MB.
MAX_CELLS = 1 << 26
MAX_RASTER_BYTES = 1 << 27
MAX_CHANNELS = 4096
MAX_NAN_OFFSETS = 64
#: Most rectangles an :class:`Arrival` lists; a frame split the way :func:`split` does
#: never needs more than its lost tiles (see :func:`regions`).
MAX_REGIONS = 4096
#: Pixel codec of each tile codec (a JPEG raster may carry full JPEG tiles).
_FAMILY = {JPEG: JPEG, JPEG_FULL: JPEG, PNG: PNG, ZLIB: ZLIB}


@dataclass(frozen=True)
class RasterHeader:
    height: int
    width: int
    channels: int              # values per cell (bytes per point for a cloud)
    dtype: np.dtype
    codec: int
    quality: int = 80
    fill: int = FILL_ZERO
    nan_offsets: Tuple[int, ...] = ()   # FILL_NAN_AT: byte offsets of float32s to NaN

    def shape(self, height: int, width: int) -> Tuple[int, ...]:
        return (height, width) if self.channels == 1 else (height, width, self.channels)


@dataclass(frozen=True)
class Tile:
    header: RasterHeader
    meta: bytes
    x: int
    y: int
    width: int
    height: int
    data: bytes

    @property
    def cells(self) -> int:
        return self.width * self.height


def header_for(pixels: np.ndarray, codec: int, quality: int = 80,
               nan_offsets: Sequence[int] = ()) -> RasterHeader:
    """Describe ``pixels`` (H x W or H x W x C) and choose how blanks are filled."""
    if pixels.ndim not in (2, 3):
        raise BridgeUsageError(f"a raster is 2- or 3-dimensional, not {pixels.shape}")
    dtype = pixels.dtype.newbyteorder("<") if pixels.dtype.byteorder == ">" else pixels.dtype
    if np.dtype(dtype).str not in _DTYPE_CODE:
        raise BridgeUsageError(f"cells of type {pixels.dtype} cannot be tiled")
    channels = pixels.shape[2] if pixels.ndim == 3 else 1
    fill = FILL_NAN_AT if len(nan_offsets) else (
        FILL_NAN if np.issubdtype(pixels.dtype, np.floating) else FILL_ZERO)
    header = RasterHeader(pixels.shape[0], pixels.shape[1], channels, np.dtype(dtype), codec,
                          quality, fill, tuple(nan_offsets))
    problem = header_problem(header)
    if problem is not None:
        raise BridgeUsageError(problem)
    return header


def header_problem(header: RasterHeader, max_bytes: int = MAX_RASTER_BYTES) -> Optional[str]:
    """What makes ``header`` unusable, or None: the one rule for both ends."""
    dtype, channels = header.dtype, header.channels
    if header.codec not in (JPEG, PNG, ZLIB):
        return f"unknown raster codec {header.codec}"
    if not 0 <= header.quality <= 100:
        return f"quality {header.quality} outside 0..100"
    if not 1 <= channels <= MAX_CHANNELS:
        return f"{channels} channels (1..{MAX_CHANNELS})"
    cells = header.height * header.width
    if not 0 < cells <= MAX_CELLS:
        return f"raster of {header.height} x {header.width} cells (1..{MAX_CELLS})"
    if cells * channels * dtype.itemsize > max_bytes:
        return (f"raster of {header.height} x {header.width} x {channels} {dtype} exceeds "
                f"{max_bytes} bytes")
    if header.codec == JPEG and (dtype != np.uint8 or channels not in (1, 3)):
        return f"JPEG takes 8-bit images of 1 or 3 channels, not {dtype} x {channels}"
    if header.codec == PNG and (dtype not in (np.uint8, np.uint16) or channels not in (1, 3, 4)):
        return f"PNG takes 8/16-bit images of 1, 3 or 4 channels, not {dtype} x {channels}"
    if header.fill == FILL_NAN and not np.issubdtype(dtype, np.floating):
        return f"NaN fill for {dtype} cells"
    if header.fill == FILL_NAN_AT:
        if dtype != np.uint8:
            return f"NaN points need byte cells, not {dtype}"
        if not 1 <= len(header.nan_offsets) <= MAX_NAN_OFFSETS:
            return f"{len(header.nan_offsets)} NaN offsets (1..{MAX_NAN_OFFSETS})"
        for offset in header.nan_offsets:
            if not 0 <= offset <= channels - 4:
                return f"NaN offset {offset} outside a {channels}-byte cell"
    elif header.fill not in (FILL_ZERO, FILL_NAN):
        return f"unknown fill {header.fill}"
    elif header.nan_offsets:
        return "NaN offsets without the NaN-at-offsets fill"
    return None


# -- JPEG without its constant header ------------------------------------------------


def _jpeg_split(jpeg: bytes) -> Tuple[int, int]:
    """``(offset of the SOF0 segment, end of the SOS header)`` of a baseline JPEG."""
    pos, sof = 2, -1
    while pos + 4 <= len(jpeg):
        if jpeg[pos] != 0xFF:
            break
        marker = jpeg[pos + 1]
        length = int.from_bytes(jpeg[pos + 2:pos + 4], "big")
        if marker == 0xC0:
            sof = pos
        if marker == 0xDA:
            return sof, pos + 2 + length
        pos += 2 + length
    return -1, -1


@lru_cache(maxsize=32)
def _jpeg_template(quality: int, channels: int) -> Optional[Tuple[bytes, int]]:
    import cv2

    blank = np.zeros((16, 16, channels) if channels == 3 else (16, 16), np.uint8)
    ok, encoded = cv2.imencode(".jpg", blank, [cv2.IMWRITE_JPEG_QUALITY, quality])
    data = encoded.tobytes()
    sof, end = _jpeg_split(data)
    if not ok or sof < 0:
        return None
    return data[:end], sof


def _jpeg_header(quality: int, channels: int, width: int, height: int) -> Optional[bytes]:
    template = _jpeg_template(quality, channels)
    if template is None:
        return None
    header, sof = template
    patched = bytearray(header)
    patched[sof + 5:sof + 7] = height.to_bytes(2, "big")
    patched[sof + 7:sof + 9] = width.to_bytes(2, "big")
    return bytes(patched)


# -- cell codecs -----------------------------------------------------------------------


def _encode_region(header: RasterHeader, region: np.ndarray) -> Tuple[int, bytes]:
    if header.codec in (JPEG, PNG):
        import cv2

        if header.codec == JPEG:
            ok, encoded = cv2.imencode(".jpg", region, [cv2.IMWRITE_JPEG_QUALITY, header.quality])
            data = encoded.tobytes()
            expected = _jpeg_header(header.quality, header.channels, region.shape[1],
                                    region.shape[0])
            if ok and expected is not None and data.startswith(expected) and \
                    data.endswith(b"\xff\xd9"):
                return JPEG, data[len(expected):-2]
            return JPEG_FULL, data
        ok, encoded = cv2.imencode(".png", region, [cv2.IMWRITE_PNG_COMPRESSION, 6])
        return PNG, encoded.tobytes()
    return ZLIB, zlib.compress(np.ascontiguousarray(region).astype(
        header.dtype.newbyteorder("<"), copy=False).tobytes(), 6)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Start-of-frame markers other than baseline SOF0: progressive, lossless, arithmetic...
_OTHER_SOF = frozenset(range(0xC1, 0xD0)) - {0xC4, 0xC8, 0xCC}
#: Markers without a length: TEM and the restart markers.
_STANDALONE = frozenset((0x01, *range(0xD0, 0xD8)))


def _declared_size(codec: int, data: bytes) -> Optional[Tuple[int, int, int]]:
    """``(height, width, channels)`` an embedded PNG or baseline JPEG declares, or None.

    Read before OpenCV sees the bytes: it would allocate whatever size they claim.
    """
    if codec == PNG:
        if len(data) < 26 or not data.startswith(_PNG_SIGNATURE) or data[12:16] != b"IHDR":
            return None
        color = data[25]
        channels = {0: 1, 2: 3, 6: 4}.get(color)
        if channels is None:
            return None
        return (int.from_bytes(data[20:24], "big"), int.from_bytes(data[16:20], "big"), channels)
    if not data.startswith(b"\xff\xd8"):
        return None
    pos, size = 2, None
    while pos + 4 <= len(data) and data[pos] == 0xFF:
        marker = data[pos + 1]
        if marker == 0xFF:  # a fill byte, as libjpeg skips it: walk the markers it walks
            pos += 1
            continue
        if marker in _STANDALONE:
            pos += 2
            continue
        length = int.from_bytes(data[pos + 2:pos + 4], "big")
        if marker in _OTHER_SOF or marker in (0xD8, 0xD9):
            return None
        if marker == 0xC0:
            if size is not None or length < 8 or pos + 10 > len(data):
                return None
            size = (int.from_bytes(data[pos + 5:pos + 7], "big"),
                    int.from_bytes(data[pos + 7:pos + 9], "big"), data[pos + 9])
        if marker == 0xDA:
            return size
        pos += 2 + length
    return None


def _decode_region(header: RasterHeader, codec: int, data: bytes, width: int,
                   height: int) -> np.ndarray:
    shape = header.shape(height, width)
    if _FAMILY.get(codec) != header.codec:
        raise BridgeProtocolError(f"tile codec {codec} in a raster of codec {header.codec}")
    if codec in (JPEG, JPEG_FULL, PNG):
        import cv2

        if codec == JPEG:
            prefix = _jpeg_header(header.quality, header.channels, width, height)
            if prefix is None:
                raise BridgeProtocolError("no JPEG header template for this quality")
            data = prefix + data + b"\xff\xd9"
        else:
            declared = _declared_size(codec, data)
            if declared != (height, width, header.channels):
                raise BridgeProtocolError(f"tile image declares {declared} (height, width, "
                                          f"channels), expected {(height, width, header.channels)}")
        try:
            image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error as exc:
            raise BridgeProtocolError(f"tile image does not decode: {exc}") from None
        if image is None or image.shape != shape or image.dtype != header.dtype:
            raise BridgeProtocolError(f"tile image does not decode to {shape} "
                                      f"{header.dtype}")
        return image
    expected = int(np.prod(shape)) * header.dtype.itemsize
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(data, expected + 1)
    except zlib.error as exc:
        raise BridgeProtocolError(f"tile does not inflate: {exc}") from None
    if len(raw) != expected or inflater.unconsumed_tail:
        raise BridgeProtocolError(f"tile inflates to {len(raw)}+ bytes, expected "
                                  f"{expected}")
    return np.frombuffer(raw, header.dtype.newbyteorder("<")).astype(
        header.dtype).reshape(shape)


# -- tile bodies -----------------------------------------------------------------------


def _put_header(out: bytearray, header: RasterHeader) -> None:
    put_varint(out, header.height)
    put_varint(out, header.width)
    put_varint(out, header.channels)
    out.append(_DTYPE_CODE[header.dtype.str])
    out.append(header.quality)
    out.append(header.fill)
    if header.fill == FILL_NAN_AT:
        put_varint(out, len(header.nan_offsets))
        for offset in header.nan_offsets:
            put_varint(out, offset)


def encode_tile(tile: Tile, codec: int) -> bytes:
    out = bytearray()
    _put_header(out, tile.header)
    put_varint(out, len(tile.meta))
    out += tile.meta
    for value in (tile.x, tile.y, tile.width, tile.height):
        put_varint(out, value)
    out.append(codec)
    out += tile.data
    return bytes(out)


def decode_tile(body: Buffer, max_bytes: int = MAX_RASTER_BYTES) -> Tuple[Tile, int]:
    """``(tile, codec)``; :class:`BridgeProtocolError` names the first bad field.

    Every header field is checked (see "Hostile input" above) before the
    caller can allocate a canvas for it; ``max_bytes`` bounds that canvas.
    """
    try:
        height, pos = get_varint(body, 0, "height")
        width, pos = get_varint(body, pos, "width")
        channels, pos = get_varint(body, pos, "channels")
        raw, pos = take(body, pos, 3, "cell type")
        dtype_code, quality, fill = raw
        if dtype_code >= len(DTYPES):
            raise BridgeProtocolError(f"bad raster header: unknown cell type {dtype_code}")
        offsets: List[int] = []
        if fill == FILL_NAN_AT:
            count, pos = get_varint(body, pos, "NaN offsets")
            if count > MAX_NAN_OFFSETS:
                raise BridgeProtocolError(f"bad raster header: {count} NaN offsets "
                                          f"(at most {MAX_NAN_OFFSETS})")
            for _ in range(count):
                offset, pos = get_varint(body, pos, "NaN offset")
                offsets.append(offset)
        meta_length, pos = get_varint(body, pos, "meta length")
        meta, pos = take(body, pos, meta_length, "meta")
        x, pos = get_varint(body, pos, "x")
        y, pos = get_varint(body, pos, "y")
        tile_width, pos = get_varint(body, pos, "tile width")
        tile_height, pos = get_varint(body, pos, "tile height")
        codec_raw, pos = take(body, pos, 1, "codec")
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"tile truncated: {exc}") from None
    codec = codec_raw[0]
    if codec not in _FAMILY:
        raise BridgeProtocolError(f"unknown tile codec {codec}")
    header = RasterHeader(height, width, channels, np.dtype(DTYPES[dtype_code]),
                          _FAMILY[codec], quality, fill, tuple(offsets))
    problem = header_problem(header, max_bytes)
    if problem is not None:
        raise BridgeProtocolError(f"bad raster header: {problem}")
    if not tile_width or not tile_height or x + tile_width > width or y + tile_height > height:
        raise BridgeProtocolError(f"tile {tile_width}x{tile_height}+{x}+{y} outside the "
                                  f"{width}x{height} raster")
    return Tile(header, meta, x, y, tile_width, tile_height, bytes(body[pos:])), codec


@dataclass(frozen=True)
class Region:
    """A rectangle of cells: columns ``x .. x + width - 1``, rows ``y .. y + height - 1``."""

    x: int
    y: int
    width: int
    height: int


@dataclass(frozen=True)
class Arrival:
    """What of one frame the receiver got: its own account, not a guess from the cells."""

    height: int
    width: int
    fraction: float              # cells that arrived / height x width
    tiles: int                   # tiles the frame was sent as
    tiles_arrived: int           # of them, how many arrived (or were repaired) and pasted
    missing: Tuple[Region, ...]  # exactly the cells that did not arrive, disjoint


def regions(mask: np.ndarray, limit: Optional[int] = None) -> List[Region]:
    """Disjoint rectangles covering exactly the True cells of a 2-D ``mask``, top to bottom.

    Cut the raster at every column and every row where the mask changes: each
    cell of that grid is then all True or all False (no change inside it, along
    either axis).  True grid cells are joined into runs along each grid row, and
    a run continues downward while the next grid row has the same run.  For a
    frame's missing cells (a union of lost tiles) that is about one rectangle
    per lost tile, or fewer where lost neighbours join.

    With ``limit``, a mask that needs more rectangles is covered by one span per
    grid row instead: every True cell still covered, some False ones too.  Only
    a peer pasting overlapping slivers makes such a frame (a lattice of them
    leaves a hole per crossing), and then the report stays small.
    """
    if mask.ndim != 2:
        raise BridgeUsageError(f"a mask is 2-dimensional, not {mask.shape}")
    if not mask.any():
        return []
    height, width = mask.shape
    xs = [0, *(np.flatnonzero((mask[:, 1:] != mask[:, :-1]).any(axis=0)) + 1).tolist(), width]
    ys = [0, *(np.flatnonzero((mask[1:] != mask[:-1]).any(axis=1)) + 1).tolist(), height]
    grid = mask[np.ix_(ys[:-1], xs[:-1])]
    exact = _sweep((_runs(row, xs) for row in grid), ys, limit)
    if exact is not None:
        return exact
    return _sweep((_span(row, xs) for row in grid), ys, None) or []


Run = Tuple[int, int]   # columns x .. x_end - 1


def _runs(row: np.ndarray, xs: List[int]) -> Set[Run]:
    """The runs of True grid cells in one grid row, in raster columns."""
    edges = np.flatnonzero(np.diff(np.concatenate(([False], row, [False])))).tolist()
    return {(xs[a], xs[b]) for a, b in zip(edges[::2], edges[1::2])}


def _span(row: np.ndarray, xs: List[int]) -> Set[Run]:
    """One run from the grid row's first True cell to its last."""
    columns = np.flatnonzero(row)
    return {(xs[columns[0]], xs[columns[-1] + 1])} if columns.size else set()


def _sweep(bands: Iterable[Set[Run]], ys: List[int], limit: Optional[int]
           ) -> Optional[List[Region]]:
    """Rectangles from the runs of each band of rows ``ys[i] .. ys[i + 1] - 1``: a run goes
    on downward while the next band has it too.  None once more than ``limit``."""
    out: List[Region] = []
    open_runs: Dict[Run, int] = {}    # run -> the row it began on
    for y, runs in zip(ys, bands):
        for run in [r for r in open_runs if r not in runs]:
            top = open_runs.pop(run)
            out.append(Region(run[0], top, run[1] - run[0], y - top))
        for run in runs:
            open_runs.setdefault(run, y)
        if limit is not None and len(out) + len(open_runs) > limit:
            return None
    out.extend(Region(run[0], top, run[1] - run[0], ys[-1] - top)
               for run, top in open_runs.items())
    return sorted(out, key=lambda r: (r.y, r.x))


def split(pixels: np.ndarray, header: RasterHeader, meta: bytes,
          budget: int = BODY_BUDGET) -> List[bytes]:
    """Tile bodies covering ``pixels``, each at most ``budget`` bytes."""
    height, width = pixels.shape[:2]
    overhead = len(encode_tile(Tile(header, meta, width, height, width, height, b""), 0)) + 4
    room = budget - overhead
    if room < 64:
        raise BridgeUsageError(f"message metadata of {len(meta)} bytes leaves no room for "
                               f"data in a datagram")
    _, whole = _encode_region(header, pixels)
    per_cell = max(len(whole) / (height * width), 1e-3)
    cells = max(1.0, 0.75 * room / per_cell)
    align = 16 if header.codec == JPEG else 1
    side = max(align, int(math.sqrt(cells)) // align * align)
    guess_w = min(width, max(1, side if height > 1 else int(cells)))
    guess_h = min(height, max(1, int(cells // guess_w)))
    # As many columns and rows as the guess needs, then tiles of equal size: a lost
    # datagram then costs 1/n of the frame, never a big tile beside slivers.
    columns = _even_cuts(width, math.ceil(width / guess_w), align)
    rows = _even_cuts(height, math.ceil(height / guess_h), align)
    bodies: List[bytes] = []
    for y, y_end in zip(rows, rows[1:]):
        for x, x_end in zip(columns, columns[1:]):
            _cover(pixels, header, meta, x, y, x_end - x, y_end - y, room, bodies)
    return bodies


def _even_cuts(length: int, parts: int, align: int) -> List[int]:
    """Where to cut ``length`` into ``parts`` near-equal pieces, at multiples of ``align``
    (JPEG codes 16-pixel blocks): ``[0, ..., length]``."""
    blocks = math.ceil(length / align)
    parts = max(1, min(parts, blocks))
    return [min(length, round(i * blocks / parts) * align) for i in range(parts + 1)]


def _cover(pixels: np.ndarray, header: RasterHeader, meta: bytes, x: int, y: int, w: int,
           h: int, room: int, out: List[bytes]) -> None:
    codec, data = _encode_region(header, pixels[y:y + h, x:x + w])
    if len(data) <= room:
        out.append(encode_tile(Tile(header, meta, x, y, w, h, data), codec))
        return
    if w * h == 1:
        raise BridgeUsageError(f"one cell encodes to {len(data)} bytes, more than a datagram")
    if w >= h:
        half = w // 2
        _cover(pixels, header, meta, x, y, half, h, room, out)
        _cover(pixels, header, meta, x + half, y, w - half, h, room, out)
    else:
        half = h // 2
        _cover(pixels, header, meta, x, y, w, half, room, out)
        _cover(pixels, header, meta, x, y + half, w, h - half, room, out)


class Canvas:
    """One frame being rebuilt from the tiles that arrive (``tiles``: how many were sent)."""

    def __init__(self, header: RasterHeader, meta: bytes, tiles: int = 0) -> None:
        problem = header_problem(header)
        if problem is not None:  # decode_tile refuses these from a peer
            raise BridgeUsageError(f"cannot paint a raster with {problem}")
        self.header = header
        self.meta = meta
        self.pixels = np.zeros(header.shape(header.height, header.width), header.dtype)
        if header.fill == FILL_NAN:
            self.pixels[...] = np.nan
        elif header.fill == FILL_NAN_AT:
            cells = self.pixels.reshape(header.height * header.width, header.channels)
            for offset in header.nan_offsets:
                cells[:, offset:offset + 4] = np.frombuffer(np.float32(np.nan).tobytes(),
                                                            np.uint8)
        self.covered = np.zeros((header.height, header.width), bool)
        self.tiles = tiles
        self.pasted = 0

    def paste(self, tile: Tile, codec: int) -> None:
        if tile.header != self.header or tile.meta != self.meta:
            raise BridgeProtocolError("tile belongs to a different frame layout")
        region = _decode_region(self.header, codec, tile.data, tile.width, tile.height)
        self.pixels[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width] = region
        self.covered[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width] = True
        self.pasted += 1

    @property
    def completeness(self) -> float:
        return float(self.covered.mean())

    def arrival(self) -> Arrival:
        return Arrival(self.header.height, self.header.width, self.completeness,
                       max(self.tiles, self.pasted), self.pasted,
                       tuple(regions(~self.covered, MAX_REGIONS)))
