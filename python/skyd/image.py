"""Images of radiance for people: a tone curve to 8-bit sRGB and a PNG
writer with the standard library alone (zlib and struct), so that writing a
fisheye needs neither PIL nor matplotlib."""

import struct
import zlib

import numpy as np

from ._sample import REC709


def luminance(rgb):
    """Rec. 709 luminance (...) of linear RGB (..., 3): cd/m2 for radiance."""
    rgb = np.asarray(rgb, dtype=np.float64)
    return REC709[0] * rgb[..., 0] + REC709[1] * rgb[..., 1] + REC709[2] * rgb[..., 2]


def auto_exposure(rgb):
    """A scale that puts the image's median luminance (of its lit pixels) at
    0.18, the middle grey a light meter aims for; the median, so that a
    sun's disk of a few pixels does not darken the sky."""
    y = luminance(rgb)
    lit = y[y > 0.0]
    return 0.18 / float(np.median(lit)) if lit.size else 1.0


def to_srgb8(rgb, scale=None):
    """Linear radiance (..., 3) to 8-bit sRGB: times scale (default
    auto_exposure), through the ACES filmic curve (Narkowicz's fit), then
    the sRGB transfer function."""
    x = np.asarray(rgb, dtype=np.float64) * (auto_exposure(rgb) if scale is None else scale)
    x = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.clip(np.rint(s * 255.0), 0, 255).astype(np.uint8)


def _chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)


def png_bytes(img):
    """A PNG file of an 8-bit image: (h, w) grey, (h, w, 3) RGB or (h, w, 4) RGBA."""
    a = np.asarray(img)
    if a.dtype != np.uint8:
        raise TypeError("png_bytes takes uint8 pixels (to_srgb8 makes them)")
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    colour = {1: 0, 3: 2, 4: 6}.get(c)
    if colour is None or not h or not w:
        raise ValueError("an image of shape %r is not grey, RGB or RGBA" % (a.shape,))
    rows = np.concatenate([np.zeros((h, 1), np.uint8), a.reshape(h, w * c)], axis=1)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)
            + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _chunk(b"IEND", b""))


def write_png(path, img):
    """Writes png_bytes(img) to path."""
    with open(path, "wb") as f:
        f.write(png_bytes(img))


def read_png(path):
    """The pixels of a PNG this module wrote (8-bit, no interlace, filter
    0): for tests and round trips, not a general decoder."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, hdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        crc = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0]
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError("a PNG chunk with a bad CRC")
        if kind == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, colour = hdr[:4]
    c = {0: 1, 2: 3, 6: 4}[colour]
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * c)
    if depth != 8 or rows[:, 0].any():
        raise ValueError("read_png reads 8-bit PNGs without filters")
    return rows[:, 1:].reshape(h, w, c)
