"""The one image decoder: padded rows, both encodings, raw and compressed alike."""
from types import SimpleNamespace

import numpy as np
import pytest

from saw_ros.vision import compressed, images


def picture(h=4, w=5):
    return np.random.default_rng(3).integers(0, 256, (h, w, 3), dtype=np.uint8)


def raw(image, encoding='bgr8', pad=0):
    """Return an Image-like message of ``image`` with ``pad`` bytes of padding after each row."""
    h, w, _ = image.shape
    rows = np.zeros((h, 3 * w + pad), np.uint8)
    rows[:, :3 * w] = image.reshape(h, 3 * w)
    rows[:, 3 * w:] = 77
    return SimpleNamespace(encoding=encoding, height=h, width=w, step=3 * w + pad,
                           data=rows.tobytes())


def test_padded_rows_are_cut_to_the_width():
    image = picture()
    decoded, encoding = images.decode(raw(image, pad=7))
    assert encoding == 'bgr8' and np.array_equal(decoded, image)
    assert not decoded.flags.owndata     # a view of the message's bytes


def test_rgb8_becomes_bgr8_for_whoever_needs_bgr():
    image = picture()
    decoded, encoding = images.decode(raw(image[:, :, ::-1], 'rgb8', pad=2))
    assert encoding == 'rgb8'
    bgr = images.to_bgr(decoded, encoding)
    assert np.array_equal(bgr, image) and bgr.flags.c_contiguous


def test_compressed_images_decode_through_the_same_function():
    image = np.full((16, 16, 3), (10, 120, 230), np.uint8)
    msg = SimpleNamespace(format='rgb8; jpeg compressed bgr8',
                          data=compressed.encode_jpeg(image, 100))
    decoded, encoding = images.decode(msg)
    assert encoding == 'rgb8'
    assert np.abs(images.to_bgr(decoded, encoding).astype(int) - image).max() <= 2


def test_other_encodings_and_short_data_are_refused():
    with pytest.raises(ValueError, match="'mono8'.*bgr8 or rgb8"):
        images.decode(raw(picture(), 'mono8'))
    short = raw(picture())
    short.data = short.data[:-1]
    with pytest.raises(ValueError, match='too short'):
        images.decode(short)
