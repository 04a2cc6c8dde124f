"""JPEG images in image_transport's compressed format: they decode to the frame."""
import cv2
import numpy as np
import pytest

from saw_ros.core import Scenario
from saw_ros.vision import compressed
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import PINK, Renderer, RobotPose
from saw_ros.vision.markers import detect, TrackerConfig
from saw_ros.vision.synthetic import evaluate
from saw_ros.vision.tracker import Tracker


def frame():
    s = Scenario()
    pose = RobotPose(x=0.0, y=s.conditions.gap / 2, theta=0.0, phase=0.3)
    return Renderer(s.robot, s.conditions.gap, CameraModel()).render(pose)


def psnr(a, b) -> float:
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return 10 * np.log10(255.0 ** 2 / mse)


def test_jpeg_at_quality_90_decodes_to_the_frame():
    image = frame()
    data = compressed.encode_jpeg(image, 90)
    assert data[:2] == b'\xff\xd8' and len(data) < image.nbytes / 10
    assert compressed.JPEG_FORMAT == 'bgr8; jpeg compressed bgr8'
    decoded, encoding = compressed.decode(compressed.JPEG_FORMAT, data)
    assert encoding == 'bgr8' and decoded.shape == image.shape
    assert psnr(decoded, image) > 35.0
    rgb, encoding = compressed.decode('rgb8; jpeg compressed bgr8', data)
    assert encoding == 'rgb8' and np.array_equal(rgb, decoded[:, :, ::-1])


def test_undecodable_data_and_other_encodings_are_refused():
    with pytest.raises(ValueError, match='does not decode'):
        compressed.decode(compressed.JPEG_FORMAT, b'not a jpeg')
    data = compressed.encode_jpeg(frame())
    with pytest.raises(ValueError, match='bgr8 or rgb8'):
        compressed.decode('mono16; jpeg compressed mono16', data)
    assert compressed.compressed_topic('/saw/camera/image_raw') == \
        '/saw/camera/image_raw/compressed'


def _discs(centres, radius=7.2):
    """Return a grey 1280x720 picture with pink discs at ``centres`` (complex px)."""
    image = np.full((720, 1280, 3), 150, np.uint8)
    for c in centres:
        Renderer._disc(image, c, radius, PINK)
    return image


def test_half_size_decode_keeps_the_marker_centres_and_areas():
    # Sub-pixel places a quarter pixel apart: a centre mapped back by half a reduced pixel
    # too few or too many would be 0.5 px off; the JPEG itself moves them by up to 0.07.
    centres = [complex(200 + 150 * k + 0.25 * k, 300 + 0.25 * (k % 3)) for k in range(6)]
    data = compressed.encode_jpeg(_discs(centres), 90)
    full, _ = compressed.decode(compressed.JPEG_FORMAT, data)
    half, _ = compressed.decode(compressed.JPEG_FORMAT, data, 2)
    assert half.shape == (360, 640, 3)
    whole = sorted(detect(full), key=lambda c: c.u)
    halved = sorted(detect(half, reduced=2), key=lambda c: c.u)
    assert len(whole) == len(halved) == len(centres)
    for c, a, b in zip(centres, whole, halved):
        assert abs(a.p - c) < 0.1 and abs(b.p - c) < 0.1, (c, a.p, b.p)
        assert abs(b.area / a.area - 1) < 0.15 and abs(b.colour - a.colour) < 0.05
    # A region of interest in the picture's pixels: the reduced pixels wholly inside it.
    config = TrackerConfig(roi=(100, 200, 471, 400))
    inside = [c.p for c in detect(half, config, reduced=2)]
    assert len(inside) == 2 and all(abs(p - c) < 0.1 for p, c in zip(
        sorted(inside, key=lambda p: p.real), centres[:2]))


def test_a_reduction_detection_cannot_take_is_refused():
    half = np.zeros((360, 640, 3), np.uint8)
    with pytest.raises(ValueError, match='divides the downscale 4'):
        detect(half, reduced=3)
    with pytest.raises(ValueError, match='divides the downscale 1'):
        detect(half, TrackerConfig(downscale=1), reduced=2)
    with pytest.raises(ValueError, match='positive integer'):
        Tracker(CameraModel()).update(half, 0.0, 0)


def test_the_tracker_on_half_size_jpegs_meets_the_accuracy_goals(level_run):
    # The vision node's path for the camera's stream (quality 90, decoded at half size)
    # against the truth, beside the same JPEGs decoded whole: measured 0.039 against 0.034 mm.
    half = evaluate(level_run, start=2.0, end=4.0, jpeg_quality=90, reduced=2)
    whole = evaluate(level_run, start=2.0, end=4.0, jpeg_quality=90)
    assert all(r.ok for r in half.results) and len(half.results) == 120
    assert half.position_rms_mm <= 0.1 and half.position_rms_mm <= 1.5 * whole.position_rms_mm
    assert half.pitch_error_deg <= 0.1


@pytest.mark.parametrize('size, slope', [((1280, 720), 0.0), ((641, 359), 0.35)])
def test_a_band_over_the_background_encodes_as_the_whole_frame(size, slope):
    # Byte for byte cv2's JPEG of the whole frame with the same restart interval, on a picture
    # of whole block rows and on one of ragged ones (a slope spreads the band over more rows).
    s = Scenario()
    camera = CameraModel(width=size[0], height=size[1], scale=600.0 * size[0] / 640, slope=slope)
    renderer = Renderer(s.robot, s.conditions.gap, camera)
    band = compressed.BandJpeg(renderer.background, 90)
    for k, x in enumerate((0.0, 0.21, -0.17, 0.33)):
        image = renderer.render(RobotPose(x=x, y=s.conditions.gap / 2, theta=0.01 * k,
                                          phase=0.9 * k))
        first, end = renderer.rows_drawn(image)
        assert 0 < first < end < size[1] and (end - first < 0.15 * size[1] or slope)
        whole = cv2.imencode('.jpg', image, band.params)[1].tobytes()
        # (and the band taken down to the bottom: its last, ragged block row)
        assert band.encode(image, first, end) == whole == band.encode(image, first, size[1])
        data = whole
        decoded, _ = compressed.decode(compressed.JPEG_FORMAT, data)
        plain, _ = compressed.decode(compressed.JPEG_FORMAT, compressed.encode_jpeg(image, 90))
        assert np.array_equal(decoded, plain)
        renderer.recycle(image)
    # Nothing drawn: the background's own JPEG; a frame of another size is refused.
    assert band.encode(renderer.background, 0, 0) == cv2.imencode(
        '.jpg', renderer.background, band.params)[1].tobytes()
    with pytest.raises(ValueError, match='background'):
        band.encode(np.zeros((16, 16, 3), np.uint8), 0, 16)


def test_a_jpeg_stream_decodes_again_only_its_rows_that_changed():
    # Every picture what decode gives, to the bit: the camera's stream (rows that stand alone)
    # at full, half and quarter size, a quality change midway (new tables: whole), a moving
    # picture (every row changes: whole), JPEGs without restart intervals, PNG, garbage.
    s = Scenario()
    renderer = Renderer(s.robot, s.conditions.gap, CameraModel())
    band = compressed.BandJpeg(renderer.background, 90)
    other = compressed.BandJpeg(renderer.background, 70)
    stream = []
    for k in range(12):
        image = renderer.render(RobotPose(x=0.004 * k, y=s.conditions.gap / 2, theta=0.0,
                                          phase=0.4 * k))
        stream.append((band if k < 8 else other).encode(image, *renderer.rows_drawn(image)))
        if k in (4, 5):
            stream.append(compressed.encode_jpeg(image))
        if k == 6:
            stream.append(cv2.imencode('.png', image)[1].tobytes())
        renderer.recycle(image)
    shifted = [cv2.imencode('.jpg', np.roll(renderer.background, 3 * k, axis=1),
                            band.params)[1].tobytes() for k in range(3)]
    for reduced in (1, 2, 4):
        jpegs = compressed.JpegStream()
        for data in stream + shifted + stream[:3]:
            got, encoding = jpegs.decode(compressed.JPEG_FORMAT, data, reduced)
            want, _ = compressed.decode(compressed.JPEG_FORMAT, data, reduced)
            assert encoding == 'bgr8' and np.array_equal(got, want)
        with pytest.raises(ValueError, match='does not decode'):
            jpegs.decode(compressed.JPEG_FORMAT, stream[0][:600], reduced)
    # Another encoding named: decoded whole, as decode does it.
    rgb, encoding = compressed.JpegStream().decode('rgb8; jpeg compressed bgr8', stream[1])
    assert encoding == 'rgb8' and np.array_equal(
        rgb, compressed.decode('rgb8; jpeg compressed bgr8', stream[1])[0])
