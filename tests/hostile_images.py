"""Image files whose headers declare a size their data does not hold, for every format the
project reads a size from: PNG (its own parser), JPEG, BMP and TIFF (Pillow's header parsers)."""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np


def png_header(width: int, height: int) -> bytes:
    """A PNG whose IHDR declares width x height 16-bit grey, with a token data chunk."""
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)

    def chunk(kind, data):
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    idat = zlib.compress(b"\x00" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def jpeg_header(width: int, height: int) -> bytes:
    """An 8x8 JPEG whose start-of-frame marker is rewritten to declare width x height."""
    data = bytearray(cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes())
    frame = data.index(b"\xff\xc0")
    data[frame + 5 : frame + 9] = struct.pack(">HH", height, width)
    return bytes(data)


def bmp_header(width: int, height: int) -> bytes:
    """The two headers of a 24-bit BMP of width x height, without pixel data."""
    info = struct.pack("<IiiHHIIiiII", 40, width, height, 1, 24, 0, 0, 2835, 2835, 0, 0)
    return b"BM" + struct.pack("<IHHI", 14 + len(info), 0, 0, 14 + len(info)) + info


def tiff_header(width: int, height: int) -> bytes:
    """A little-endian TIFF whose one directory describes an 8-bit grey width x height strip
    the file does not hold."""
    tags = [(256, 4, width), (257, 4, height), (258, 3, 8), (259, 3, 1), (262, 3, 1),
            (273, 4, 8), (278, 4, height), (279, 4, width * height)]  # fmt: skip
    entries = b"".join(struct.pack("<HHII", tag, kind, 1, value) for tag, kind, value in tags)
    return b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(tags)) + entries + b"\0" * 4


HEADERS = {"png": png_header, "jpg": jpeg_header, "bmp": bmp_header, "tif": tiff_header}
"""Header writer by file extension."""
