"""Tiles: every tile fits a datagram and decodes alone; lost tiles are blank or NaN, and
the canvas says exactly which cells they were."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.wire import tiles
from bridge.wire import datagrams
from bridge.wire.datagrams import BODY_BUDGET, Datagram
from bridge.wire.link import DatagramOpener, DatagramSealer
from codec_helpers import FUZZ

KEY = bytes(range(32))


def camera_image(height: int = 240, width: int = 320) -> np.ndarray:
    """Smooth gradients with a textured patch, like a rendered scene."""
    yy, xx = np.mgrid[0:height, 0:width]
    image = np.stack([xx * 255 // width, yy * 255 // height, (xx + yy) % 256], -1)
    image = image.astype(np.uint8)
    rng = np.random.default_rng(0)
    patch = image[height // 5:height // 2, width // 5:width // 2]
    patch[...] = rng.integers(0, 256, patch.shape, dtype=np.uint8)
    return image


def assemble(bodies, keep=lambda index: True):
    canvas = None
    for index, body in enumerate(bodies):
        if not keep(index):
            continue
        tile, codec = tiles.decode_tile(body)
        canvas = canvas or tiles.Canvas(tile.header, tile.meta)
        canvas.paste(tile, codec)
    return canvas


def test_jpeg_tiles_fit_and_rebuild_the_image():
    image = camera_image()
    bodies = tiles.split(image, tiles.header_for(image, tiles.JPEG, 85), b"meta")
    assert len(bodies) > 4 and all(len(body) <= BODY_BUDGET for body in bodies)
    canvas = assemble(bodies)
    assert canvas.completeness == 1.0 and canvas.meta == b"meta"
    error = np.abs(canvas.pixels.astype(int) - image)
    assert error[120:].mean() < 3 and error.mean() < 8  # JPEG at 85 %, noise patch included


@pytest.mark.parametrize("height, width", [(120, 160), (240, 320), (544, 1024), (480, 640)])
def test_a_frame_is_cut_into_near_equal_tiles(height, width):
    """A lost datagram costs about 1/n of the frame: no big tile beside slivers (a
    160 x 120 image was once a 65 % tile and three small ones)."""
    yy, xx = np.mgrid[0:height, 0:width]
    image = np.stack([xx % 256, yy * 255 // height, (xx + yy) % 256], -1).astype(np.uint8)
    bodies = tiles.split(image, tiles.header_for(image, tiles.JPEG, 80), b"")
    shares = [tiles.decode_tile(body)[0].cells / (height * width) for body in bodies]
    assert sum(shares) == pytest.approx(1.0)
    assert max(shares) <= 1.6 * min(shares), shares     # within a 16-pixel block row/column


def test_jpeg_tiles_do_not_carry_the_jpeg_header():
    image = camera_image()
    bodies = tiles.split(image, tiles.header_for(image, tiles.JPEG, 85), b"")
    assert not any(b"JFIF" in body for body in bodies)


def test_a_lost_tile_leaves_a_blank_region_and_the_rest_intact():
    image = camera_image()
    bodies = tiles.split(image, tiles.header_for(image, tiles.PNG), b"")
    canvas = assemble(bodies, keep=lambda index: index != 1)
    assert 0.5 < canvas.completeness < 1.0
    assert np.array_equal(canvas.pixels[canvas.covered], image[canvas.covered])  # lossless
    assert not canvas.pixels[~canvas.covered].any()


def test_float_depth_marks_missing_pixels_nan():
    depth = np.random.default_rng(1).random((60, 80), dtype=np.float32)
    bodies = tiles.split(depth, tiles.header_for(depth, tiles.ZLIB), b"")
    canvas = assemble(bodies, keep=lambda index: index % 2 == 0)
    assert np.isnan(canvas.pixels[~canvas.covered]).all()
    assert np.array_equal(canvas.pixels[canvas.covered], depth[canvas.covered])


def test_cloud_tiles_are_small_clouds_with_nan_points_for_the_missing():
    rng = np.random.default_rng(2)
    xyz = rng.random((48, 64, 4), dtype=np.float32)
    cells = xyz.view(np.uint8).reshape(48, 64, 16)
    bodies = tiles.split(cells, tiles.header_for(cells, tiles.ZLIB, nan_offsets=(0, 4, 8)),
                         b"fields")
    canvas = assemble(bodies, keep=lambda index: index != 0)
    points = canvas.pixels.view(np.float32).reshape(48, 64, 4)
    missing = ~canvas.covered
    assert missing.any()
    assert np.isnan(points[missing][:, :3]).all() and (points[missing][:, 3] == 0).all()
    assert np.array_equal(points[canvas.covered], xyz[canvas.covered])


def test_unorganized_clouds_are_split_along_their_row():
    cells = np.random.default_rng(3).integers(0, 255, (1, 5000, 16), dtype=np.uint8)
    bodies = tiles.split(cells, tiles.header_for(cells, tiles.ZLIB), b"")
    assert len(bodies) > 40
    assert assemble(bodies).completeness == 1.0


# -- what arrived: the canvas's account, never the pixels' look ------------------------------


def painted(regions, shape) -> np.ndarray:
    """How many of ``regions`` cover each cell."""
    count = np.zeros(shape, int)
    for r in regions:
        assert r.width > 0 and r.height > 0
        assert 0 <= r.x and r.x + r.width <= shape[1] and 0 <= r.y and r.y + r.height <= shape[0]
        count[r.y:r.y + r.height, r.x:r.x + r.width] += 1
    return count


@FUZZ
@given(st.integers(1, 24), st.integers(1, 24), st.lists(st.tuples(
    st.integers(0, 23), st.integers(0, 23), st.integers(1, 24), st.integers(1, 24)),
    max_size=8), st.booleans())
def test_regions_cover_exactly_the_marked_cells_once(height, width, rectangles, invert):
    """Unions of tiles, their complements (what is missing), and whatever else."""
    mask = np.zeros((height, width), bool)
    for x, y, w, h in rectangles:
        mask[y:y + h, x:x + w] = True
    mask = ~mask if invert else mask
    assert np.array_equal(painted(tiles.regions(mask), mask.shape), mask.astype(int))


@FUZZ
@given(st.lists(st.booleans(), min_size=1, max_size=120), st.integers(1, 12))
def test_regions_of_any_mask_are_exact(cells, width):
    mask = np.array(cells + [False] * (-len(cells) % width)).reshape(-1, width)
    assert np.array_equal(painted(tiles.regions(mask), mask.shape), mask.astype(int))


@FUZZ
@given(st.lists(st.booleans(), min_size=1, max_size=120), st.integers(1, 12),
       st.integers(1, 6))
def test_past_the_limit_regions_still_cover_every_marked_cell_once(cells, width, limit):
    mask = np.array(cells + [False] * (-len(cells) % width)).reshape(-1, width)
    exact = tiles.regions(mask)
    bounded = tiles.regions(mask, limit)
    count = painted(bounded, mask.shape)
    assert count.max(initial=0) <= 1 and (count[mask] == 1).all()
    assert bounded == exact if len(exact) <= limit else len(bounded) <= mask.shape[0]


def test_a_lattice_of_slivers_from_a_peer_makes_a_short_report():
    """Overlapping one-cell-wide tiles, every 2nd row and column: a hole per crossing,
    40 000 of them, reported as at most one rectangle per row band."""
    header = tiles.RasterHeader(400, 400, 1, np.dtype(np.uint8), tiles.ZLIB)
    canvas = tiles.Canvas(header, b"", 400)
    for line in range(0, 400, 2):
        for x, y, w, h in ((0, line, 400, 1), (line, 0, 1, 400)):
            data = zlib.compress(bytes(w * h))
            canvas.paste(tiles.Tile(header, b"", x, y, w, h, data), tiles.ZLIB)
    arrival = canvas.arrival()
    assert len(arrival.missing) <= 200 and arrival.fraction == pytest.approx(0.75)
    count = painted(arrival.missing, (400, 400))
    assert (count[~canvas.covered] == 1).all()


def test_lost_tiles_are_their_own_regions():
    mask = np.zeros((120, 160), bool)
    mask[0:60, 40:80] = True        # two lost tiles, one under the other: one region
    mask[60:120, 40:80] = True
    mask[0:60, 120:160] = True      # and one alone
    assert tiles.regions(mask) == [tiles.Region(40, 0, 40, 120), tiles.Region(120, 0, 40, 60)]
    assert tiles.regions(np.zeros((3, 3), bool)) == []
    with pytest.raises(BridgeUsageError, match="2-dimensional"):
        tiles.regions(np.zeros(3, bool))


@pytest.mark.parametrize("codec", [tiles.JPEG, tiles.PNG])
def test_the_arrival_names_the_tiles_not_pasted_yet_fed_one_at_a_time(codec):
    image = camera_image()
    bodies = tiles.split(image, tiles.header_for(image, codec, 85), b"meta")
    rectangles = [tiles.decode_tile(body)[0] for body in bodies]
    order = np.random.default_rng(4).permutation(len(bodies))
    tile, _ = tiles.decode_tile(bodies[order[0]])
    canvas = tiles.Canvas(tile.header, tile.meta, len(bodies))
    assert canvas.arrival().missing == (tiles.Region(0, 0, 320, 240),)
    for fed, index in enumerate(order, 1):
        canvas.paste(*tiles.decode_tile(bodies[index]))
        lost = np.zeros((240, 320), bool)
        for other in order[fed:]:
            t = rectangles[other]
            lost[t.y:t.y + t.height, t.x:t.x + t.width] = True
        arrival = canvas.arrival()
        assert np.array_equal(painted(arrival.missing, lost.shape), lost.astype(int))
        assert (arrival.tiles, arrival.tiles_arrived) == (len(bodies), fed)
        assert arrival.fraction == pytest.approx(1 - lost.mean())
        assert (arrival.height, arrival.width) == (240, 320)
    assert canvas.arrival().missing == () and canvas.arrival().fraction == 1.0


def test_a_black_sky_and_points_without_depth_are_content_not_loss():
    sky = camera_image()
    sky[:150] = 0                                     # most of the frame exactly black
    bodies = tiles.split(sky, tiles.header_for(sky, tiles.PNG), b"")
    arrival = assemble(bodies).arrival()
    assert arrival.fraction == 1.0 and arrival.missing == ()
    xyz = np.full((48, 64, 4), np.nan, np.float32)     # no depth anywhere
    cells = xyz.view(np.uint8).reshape(48, 64, 16)
    bodies = tiles.split(cells, tiles.header_for(cells, tiles.ZLIB, nan_offsets=(0, 4, 8)), b"")
    arrival = assemble(bodies).arrival()
    assert arrival.fraction == 1.0 and arrival.missing == ()
    assert arrival.tiles == arrival.tiles_arrived == len(bodies)


def test_a_tile_that_cannot_fit_is_a_usage_error():
    with pytest.raises(BridgeUsageError, match="no room"):
        tiles.split(camera_image(16, 16), tiles.header_for(camera_image(16, 16), tiles.PNG),
                    bytes(BODY_BUDGET))


def test_bad_headers_are_refused():
    image = camera_image(32, 32)
    with pytest.raises(BridgeUsageError, match="JPEG"):
        tiles.header_for(image.astype(np.uint16), tiles.JPEG)
    body = tiles.split(image, tiles.header_for(image, tiles.PNG), b"")[0]
    tile, codec = tiles.decode_tile(body)
    other = tiles.Canvas(tiles.header_for(camera_image(16, 16), tiles.PNG), b"")
    with pytest.raises(BridgeProtocolError, match="different frame"):
        other.paste(tile, codec)


@FUZZ
@given(st.binary(max_size=300))
def test_any_bytes_paint_their_own_rectangle_or_raise_the_peer_error(data):
    try:
        tile, codec = tiles.decode_tile(data)
        canvas = tiles.Canvas(tile.header, tile.meta)
        canvas.paste(tile, codec)
    except BridgeProtocolError:
        return
    # accepted: it painted exactly the rectangle it names, and nothing else
    painted = np.zeros_like(canvas.covered)
    painted[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width] = True
    assert (canvas.covered == painted).all() and canvas.pasted == 1


@pytest.mark.parametrize("data", [b"", b"\x00" * 8, bytes(range(40)), b"\xff" * 300])
def test_plain_garbage_raises_the_peer_error(data):
    with pytest.raises(BridgeProtocolError):
        tiles.decode_tile(data)


@FUZZ
@given(st.integers(0, 10_000), st.integers(1, 255))
@example(index=5, flip=1)  # first CI failure: the fill byte became NaN on a uint8 raster
@example(index=8, flip=1)  # a tile's x: the tile layer alone would paint it a column off
def test_a_corrupted_tile_never_paints_garbage_silently(index, flip):
    """A tile travels in a sealed datagram (``bridge.wire.link``): one byte flipped anywhere on the
    wire is refused before any cell is painted.  (The tile layer alone checks its header
    fields and the zlib stream's checksum, not a tile's place or a JPEG's bytes: the seal
    does.)  Whatever is painted is compared with the image, cell by cell."""
    image = camera_image(64, 64)
    bodies = tiles.split(image, tiles.header_for(image, tiles.ZLIB), b"m")
    opener = DatagramOpener()
    opener.install(KEY)
    sealer = DatagramSealer(KEY)
    wires = [bytearray(sealer.seal(datagrams.encode(Datagram(7, 0, 1, len(bodies), 1, n, body))))
             for n, body in enumerate(bodies)]
    hit = index % sum(map(len, wires))
    for wire in wires:                                  # flip byte ``hit`` of the whole frame
        if hit < len(wire):
            wire[hit] ^= flip
            break
        hit -= len(wire)
    canvas, refused = None, 0
    for wire in wires:
        try:
            tile, codec = tiles.decode_tile(datagrams.decode(opener.open(bytes(wire))).body)
            canvas = canvas or tiles.Canvas(tile.header, tile.meta)
            canvas.paste(tile, codec)
        except BridgeProtocolError:
            refused += 1
    assert refused == 1, f"{refused} of {len(wires)} tiles refused with one byte flipped"
    assert canvas is not None and canvas.pixels.shape == image.shape
    assert canvas.pasted == len(wires) - 1 and 0 < canvas.completeness < 1
    assert (canvas.pixels[canvas.covered] == image[canvas.covered]).all(), \
        "a painted cell is not the image's"


def zlib_tile(image=None):
    image = camera_image(16, 16) if image is None else image
    return bytearray(tiles.split(image, tiles.header_for(image, tiles.ZLIB), b"m")[0])


@pytest.mark.parametrize("offset, value, problem", [
    (5, 1, "NaN fill for uint8 cells"),          # fill byte of the CI failure
    (3, 200, "unknown cell type 200"),
    (4, 101, "quality 101 outside 0..100"),
    (5, 9, "unknown fill 9"),
    (2, 0, "0 channels"),
    (0, 0, "raster of 0 x 16 cells"),
])
def test_every_raster_header_field_is_checked_by_name(offset, value, problem):
    body = zlib_tile()
    assert body[:6] == bytes((16, 16, 3, 0, 80, 0))  # height width channels dtype quality fill
    body[offset] = value
    with pytest.raises(BridgeProtocolError, match=problem):
        tiles.decode_tile(bytes(body))


def test_a_tiny_tile_cannot_claim_a_huge_raster():
    body = zlib_tile()
    huge = tiles.Tile(tiles.RasterHeader(1 << 13, 1 << 13, 3, np.dtype(np.uint8), tiles.ZLIB),
                      b"m", 0, 0, 1, 1, b"")
    with pytest.raises(BridgeProtocolError, match="exceeds 134217728 bytes"):
        tiles.decode_tile(tiles.encode_tile(huge, tiles.ZLIB))
    with pytest.raises(BridgeProtocolError, match="exceeds 500 bytes"):
        tiles.decode_tile(bytes(body), max_bytes=500)


def test_nan_points_need_byte_cells_inside_the_cell():
    floats = np.zeros((4, 4, 4), np.float32)
    with pytest.raises(BridgeUsageError, match="NaN points need byte cells"):
        tiles.header_for(floats, tiles.ZLIB, nan_offsets=(0,))
    cells = np.zeros((4, 4, 8), np.uint8)
    with pytest.raises(BridgeUsageError, match="NaN offset 5 outside"):
        tiles.header_for(cells, tiles.ZLIB, nan_offsets=(5,))
    with pytest.raises(BridgeUsageError, match="quality 120"):
        tiles.header_for(camera_image(8, 8), tiles.JPEG, 120)


def test_full_jpeg_tiles_paste_beside_headerless_ones():
    import cv2

    image = camera_image(64, 128)
    header = tiles.header_for(image, tiles.JPEG, 85)
    bodies = tiles.split(image, header, b"", budget=600)
    assert len(bodies) > 1
    tile, codec = tiles.decode_tile(bodies[0])
    full = cv2.imencode(".jpg", image[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width],
                        [cv2.IMWRITE_JPEG_QUALITY, 85])[1].tobytes()
    replaced = tiles.encode_tile(tiles.Tile(header, b"", tile.x, tile.y, tile.width,
                                            tile.height, full), tiles.JPEG_FULL)
    canvas = assemble([replaced, *bodies[1:]])
    assert canvas.completeness == 1.0


@pytest.mark.parametrize("codec", [tiles.PNG, tiles.JPEG_FULL])
def test_an_embedded_image_must_declare_the_tiles_size_before_decoding(codec):
    import cv2

    big = camera_image(64, 64)
    data = cv2.imencode(".png" if codec == tiles.PNG else ".jpg", big)[1].tobytes()
    header = tiles.header_for(camera_image(16, 16), tiles.PNG if codec == tiles.PNG else tiles.JPEG)
    body = tiles.encode_tile(tiles.Tile(header, b"", 0, 0, 16, 16, data), codec)
    tile, got = tiles.decode_tile(body)
    with pytest.raises(BridgeProtocolError, match=r"declares \(64, 64, 3\)"):
        tiles.Canvas(tile.header, tile.meta).paste(tile, got)
    other = tiles.encode_tile(tiles.Tile(header, b"", 0, 0, 16, 16, b"GIF89a" + bytes(40)),
                              codec)
    tile, got = tiles.decode_tile(other)
    with pytest.raises(BridgeProtocolError, match="declares None"):
        tiles.Canvas(tile.header, tile.meta).paste(tile, got)


def test_the_size_check_walks_jpeg_markers_as_libjpeg_does():
    import cv2

    image = camera_image(16, 16)
    data = cv2.imencode(".jpg", image)[1].tobytes()
    sof = data.index(b"\xff\xc0")
    padded = data[:sof] + b"\xff\xff" + data[sof:]  # fill bytes before SOF0 (legal JPEG)
    header = tiles.header_for(image, tiles.JPEG)
    tile, codec = tiles.decode_tile(tiles.encode_tile(
        tiles.Tile(header, b"", 0, 0, 16, 16, padded), tiles.JPEG_FULL))
    canvas = tiles.Canvas(tile.header, tile.meta)
    canvas.paste(tile, codec)
    assert canvas.completeness == 1.0
