"""Tiles: every tile fits a datagram and decodes alone; lost tiles are blank or NaN."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge import tiles
from bridge.datagrams import BODY_BUDGET
from bridge.errors import BridgeProtocolError, BridgeUsageError
from codec_helpers import FUZZ


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
def test_garbage_tiles_raise_the_peer_error(data):
    try:
        tile, codec = tiles.decode_tile(data)
        tiles.Canvas(tile.header, tile.meta).paste(tile, codec)
    except BridgeProtocolError:
        pass


@FUZZ
@given(st.integers(0, 200), st.integers(1, 255))
def test_a_corrupted_tile_never_paints_garbage_silently(index, flip):
    image = camera_image(64, 64)
    body = bytearray(tiles.split(image, tiles.header_for(image, tiles.ZLIB), b"m")[0])
    body[index % len(body)] ^= flip
    try:
        tile, codec = tiles.decode_tile(bytes(body))
        tiles.Canvas(tile.header, tile.meta).paste(tile, codec)
    except BridgeProtocolError:
        pass
