"""
JPEG images as image_transport's ``compressed`` plugin sends them (sensor_msgs/CompressedImage).

The plugin writes ``format`` as '<encoding>; jpeg compressed <target encoding>' and ``data`` as the
JPEG file's bytes; a bgr8 frame goes out as 'bgr8; jpeg compressed bgr8'. Pure (numpy + OpenCV).
"""
from __future__ import annotations

import re
from typing import List, Optional

import cv2
import numpy as np

JPEG_FORMAT = 'bgr8; jpeg compressed bgr8'
TRANSPORTS = ('raw', 'compressed')
DEFAULT_QUALITY = 90        # image_transport's jpeg_quality default
REDUCED_FLAGS = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2,
                 4: cv2.IMREAD_REDUCED_COLOR_4, 8: cv2.IMREAD_REDUCED_COLOR_8}


def encode_jpeg(frame: np.ndarray, quality: int = DEFAULT_QUALITY) -> bytes:
    """Return the JPEG bytes of a bgr8 frame (H x W x 3 uint8)."""
    ok, buf = cv2.imencode('.jpg', frame, [int(cv2.IMWRITE_JPEG_QUALITY), int(quality)])
    if not ok:
        raise ValueError('JPEG encoding failed')
    return buf.tobytes()


class BandJpeg:
    """
    JPEGs of frames that are one background but for a band of rows: only the band is encoded.

    Each row of 16 x 16 blocks (4:2:0) is a restart interval of its own, which a decoder reads
    with no reference to the rows before it (that is what restart markers are for): the
    background's rows are encoded once, and a frame's JPEG is theirs with the band's rows,
    encoded alone, put in their place. Byte for byte what ``cv2.imencode`` makes of the whole
    frame with the same restart interval (tests/vision/test_vision_compressed.py); its pixels
    decode as those of ``encode_jpeg`` (restart markers change no coefficient). The camera's
    robot and surfaces span a tenth of the rows: 0.2 ms a frame against 1.5 at 1280x720.
    """

    MCU = 16                        # rows of a block row at 4:2:0

    def __init__(self, background: np.ndarray, quality: int = DEFAULT_QUALITY):
        self.background = background
        height, width = background.shape[:2]
        self.rows = -(-height // self.MCU)
        self.params = [int(cv2.IMWRITE_JPEG_QUALITY), int(quality),
                       int(cv2.IMWRITE_JPEG_SAMPLING_FACTOR),
                       int(cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420),
                       int(cv2.IMWRITE_JPEG_RST_INTERVAL), -(-width // self.MCU)]
        self.head, self.segments = self._split(self._encode(background))

    def _encode(self, image: np.ndarray) -> bytes:
        ok, buf = cv2.imencode('.jpg', image, self.params)
        if not ok:
            raise ValueError('JPEG encoding failed')
        return buf.tobytes()

    @staticmethod
    def _split(data: bytes):
        """Return (the headers up to the scan's data, the entropy-coded data of each row)."""
        at = 2
        while data[at + 1] != 0xDA:             # to the start of scan
            at += 2 + int.from_bytes(data[at + 2:at + 4], 'big')
        start = at + 2 + int.from_bytes(data[at + 2:at + 4], 'big')
        segments = _intervals(data[start:-2])   # (the last two bytes: end of image)
        if segments is None:
            raise ValueError('a marker in the scan other than restart markers')
        return data[:start], segments

    def encode(self, frame: np.ndarray, first: int, end: int) -> bytes:
        """Return the JPEG of ``frame``, the background's but in rows first .. end - 1."""
        if frame.shape != self.background.shape:
            raise ValueError(f'frame {frame.shape}, background {self.background.shape}')
        a, b = max(first, 0) // self.MCU, min(-(-end // self.MCU), self.rows)
        if a >= b:
            segments = self.segments
        else:
            band = self._split(self._encode(frame[a * self.MCU:b * self.MCU]))[1]
            if len(band) != b - a:
                raise ValueError(f'{len(band)} restart intervals for {b - a} block rows')
            segments = self.segments[:a] + band + self.segments[b:]
        parts = [self.head]
        for k, segment in enumerate(segments):
            parts.append(segment)
            if k < len(segments) - 1:
                parts.append(RESTART[k % 8])
        parts.append(b'\xff\xd9')
        return b''.join(parts)


RESTART = tuple(bytes((0xFF, 0xD0 + k)) for k in range(8))


class JpegStream:
    """
    Decodes a camera's JPEG stream, decoding again only the block rows that changed.

    A JPEG whose every row of blocks is a restart interval (``BandJpeg``'s) is split there; the
    rows whose bytes (and headers) are those of the last frame decode to the same pixels, so
    only a strip of the others, with one row more each side (chroma upsampling reads across
    rows), is made into a JPEG of its own and decoded, and replaces the last picture's rows but
    for its outermost pixel rows. The picture is what ``decode`` gives, to the bit (tests); any
    other JPEG, PNG, or a stream whose rows all change (a moving camera) is decoded whole. The
    camera's robot spans a tenth of its rows: 0.4 ms a frame against 1.1 at 1280x720, half
    size. The picture returned is overwritten by the next ``decode``.
    """

    def __init__(self):
        self._last = None       # (headers, rows' bytes, reduced, picture) of the last frame

    def decode(self, format_: str, data, reduced: int = 1) -> tuple:
        """Return (H x W x 3 uint8 image, encoding), as ``decode`` (module function) does."""
        data = bytes(data)
        bgr = (format_.split(';')[0].strip() if ';' in format_ else 'bgr8') == 'bgr8'
        parts = _rows_of(data) if bgr else None
        last, self._last = self._last, None
        if parts is None:
            return decode(format_, data, reduced)
        head, rows, height_at, mcu = parts
        changed = None
        if last is not None and last[0] == head and last[2] == reduced and \
                len(last[1]) == len(rows):
            changed = [k for k, (a, b) in enumerate(zip(last[1], rows)) if a != b]
        image = None
        if changed is not None and len(changed) <= len(rows) // 2:
            image = last[3]
            if changed:
                image = self._patch(image, head, rows, height_at, mcu, changed, reduced)
        if image is None:
            image, encoding = decode(format_, data, reduced)
        self._last = (head, rows, reduced, image)
        return image, 'bgr8'

    @staticmethod
    def _patch(image, head, rows, height_at, mcu, changed, reduced):
        """Decode rows changed[0] - 1 .. changed[-1] + 1 alone into ``image`` (None: failed)."""
        a, b = max(changed[0] - 1, 0), min(changed[-1] + 2, len(rows))
        height = int.from_bytes(head[height_at:height_at + 2], 'big')
        strip_height = min(b * mcu, height) - a * mcu
        strip_head = head[:height_at] + strip_height.to_bytes(2, 'big') + head[height_at + 2:]
        body = [strip_head]
        for k, row in enumerate(rows[a:b]):
            body.append(row)
            if k < b - a - 1:
                body.append(RESTART[k % 8])
        body.append(b'\xff\xd9')
        strip = cv2.imdecode(np.frombuffer(b''.join(body), np.uint8), REDUCED_FLAGS[reduced])
        if strip is None:
            return None
        # All but the strip's first and last pixel rows: their upsampled chroma would read the
        # block rows beyond, which the strip lacks (the picture's own edges are the strip's).
        # The rows next to a changed one change too, for the same reason: they are in it.
        r = mcu // reduced
        top = 0 if a == 0 else 1
        end = strip.shape[0] if b == len(rows) else strip.shape[0] - 1
        if strip.shape[1] != image.shape[1] or a * r + strip.shape[0] > image.shape[0]:
            return None
        image[a * r + top:a * r + end] = strip[top:end]
        return image


_MARKER = re.compile(b'\xff[^\x00]')


def _intervals(scan: bytes) -> Optional[List[bytes]]:
    """
    Return a scan's entropy-coded bytes cut at its restart markers (None: it holds another).

    In the coded bytes 0xFF is followed by 0x00 (a byte of data) or by a marker. One regular
    expression finds the markers, not a Python loop over the 0xFF bytes: a 1280x720 frame at
    quality 90 holds 1200 of them, 0.15 ms of Python.
    """
    segments, begin = [], 0
    for marker in _MARKER.finditer(scan):
        at = marker.start()
        if not 0xD0 <= scan[at + 1] <= 0xD7:
            return None
        segments.append(scan[begin:at])
        begin = at + 2
    segments.append(scan[begin:])
    return segments


def _rows_of(data: bytes):
    """
    Return (headers, each block row's entropy-coded bytes, offset of the height, block rows' px).

    None unless ``data`` is a baseline JPEG of one scan whose restart interval is one row of
    blocks (every row's bytes then stand alone).
    """
    try:
        if data[:2] != b'\xff\xd8':
            return None
        at, height_at, width, mcu, mcu_w, interval = 2, None, 0, 0, 0, 0
        while True:
            if data[at] != 0xFF:
                return None
            marker = data[at + 1]
            size = int.from_bytes(data[at + 2:at + 4], 'big')
            if marker in (0xC0, 0xC1):               # baseline / extended Huffman
                height_at = at + 5
                width = int.from_bytes(data[at + 7:at + 9], 'big')
                n = data[at + 9]
                sampling = [data[at + 11 + 3 * k] for k in range(n)]
                mcu = 8 * max(s & 15 for s in sampling)
                mcu_w = 8 * max(s >> 4 for s in sampling)
            elif 0xC2 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                return None                          # progressive, lossless, arithmetic
            elif marker == 0xDD:
                interval = int.from_bytes(data[at + 4:at + 6], 'big')
            elif marker == 0xDA:
                start = at + 2 + size
                break
            at += 2 + size
        if height_at is None or not mcu or interval != -(-width // mcu_w):
            return None
        height = int.from_bytes(data[height_at:height_at + 2], 'big')
        if data[-2:] != b'\xff\xd9' or not height:
            return None
        rows = _intervals(data[start:-2])
        if rows is None or len(rows) != -(-height // mcu):
            return None
        return data[:start], rows, height_at, mcu
    except IndexError:
        return None


def decode(format_: str, data, reduced: int = 1) -> tuple:
    """
    Return (H x W x 3 uint8 image, encoding) of a CompressedImage's format and data.

    The encoding is the one the format names before ';' (bgr8 or rgb8; bgr8 when the format names
    none, as OpenCV decodes to BGR); ValueError for data that does not decode.

    ``reduced`` 2, 4 or 8: the picture at 1 / ``reduced`` of its size (rounded up), which a JPEG
    decoder makes in its inverse DCT for less than a full decode costs (1280x720 at quality 90:
    1.1 ms against 1.7); a PNG is decoded whole, then shrunk (INTER_AREA).
    """
    image = cv2.imdecode(np.frombuffer(data, np.uint8), REDUCED_FLAGS[reduced])
    if image is None:
        raise ValueError(f'compressed image ({format_!r}, {len(data)} bytes) does not decode')
    encoding = format_.split(';')[0].strip() if ';' in format_ else 'bgr8'
    if encoding == 'rgb8':
        image = np.ascontiguousarray(image[:, :, ::-1])
    elif encoding != 'bgr8':
        raise ValueError(f'unsupported compressed image format {format_!r}: bgr8 or rgb8 only')
    return image, encoding


def compressed_topic(image_topic: str) -> str:
    """Return image_transport's topic for the compressed stream of ``image_topic``."""
    return image_topic.rstrip('/') + '/compressed'
