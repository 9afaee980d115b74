"""Framing photos like the training renders: find the object on a plain background, crop a
square in which it fills FRAME_FILL of the side; leave cluttered or empty pictures alone."""
import numpy as np
import pytest
import torch

from model.encoders.framing import FRAME_FILL, find_object, frame_object

torch.set_num_threads(1)


def _picture(h=300, w=400, bg=(0.6, 0.62, 0.58)):
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:] = bg
    rgb[100:160, 250:290] = (0.9, 0.1, 0.1)       # a 60 x 40 object right of the centre
    return rgb


def test_an_object_on_a_plain_background_is_cropped_to_the_training_fill():
    rgb = _picture()
    f = find_object(rgb)
    assert f.reason == "object" and f.box == (100, 250, 160, 290)
    assert np.allclose(f.background, (0.6, 0.62, 0.58))
    out = frame_object(rgb)
    side = int(np.ceil(60 / FRAME_FILL))
    assert out.shape == (side, side, 3)
    g = find_object(out)
    y0, x0, y1, x1 = g.box
    assert (y1 - y0, x1 - x0) == (60, 40)
    assert abs((y0 + y1) / 2 - side / 2) <= 1 and abs((x0 + x1) / 2 - side / 2) <= 1   # centred
    assert np.allclose(out[0, 0], (0.6, 0.62, 0.58))
    # near the picture's edge the square leaves it and is padded with the border colour
    edge = _picture()
    edge[:, :] = (0.6, 0.62, 0.58)
    edge[5:65, 355:395] = (0.9, 0.1, 0.1)
    out = frame_object(edge)
    assert out.shape == (side, side, 3) and find_object(out).box[2] - find_object(out).box[0] == 60


def test_a_large_photo_is_searched_on_a_strided_copy():
    rgb = np.empty((1500, 2000, 3), np.float32)
    rgb[:] = (0.2, 0.25, 0.3)
    rgb[700:1000, 1200:1400] = (0.9, 0.8, 0.1)        # 300 x 200 object
    out = frame_object(rgb)
    side = out.shape[0]
    assert out.shape == (side, side, 3) and abs(side - 300 / FRAME_FILL) <= 8
    y0, x0, y1, x1 = find_object(out).box
    assert abs((y1 - y0) - 300) <= 4 and abs((x1 - x0) - 200) <= 4


def test_pictures_without_a_plain_background_or_object_are_left_alone():
    rng = np.random.default_rng(0)
    cluttered = rng.random((200, 260, 3)).astype(np.float32)
    assert find_object(cluttered).reason == "cluttered border"
    assert frame_object(cluttered) is cluttered
    empty = np.full((120, 90, 3), 0.3, np.float32)
    assert find_object(empty).reason == "no object"
    assert frame_object(empty) is empty
    # an object that already fills the frame: only padded to a square with the border colour
    big = _picture(100, 160)
    big[10:90, 20:140] = (0.1, 0.2, 0.9)
    out = frame_object(big)
    assert out.shape == (160, 160, 3)
    assert np.allclose(out[0, 0], (0.6, 0.62, 0.58)) and np.array_equal(out[30:130], big)
    with pytest.raises(ValueError):
        frame_object(big, fill=0.0)


def test_framing_a_distant_render_brings_back_the_renders_tokens(tmp_path):
    """A render shown small in a larger picture (a photo from further away) encodes closer to
    the render itself once framed than read whole."""
    from PIL import Image

    from model.core.example import example_objects
    from model.encoders.image import ImageEncoder, ImageEncoderConfig, preprocess
    from model.imaging.evaluate import farther_view
    from model.imaging.render import render_view, sample_views

    obj = example_objects()["cabinet"]
    view = sample_views("cab", [p.label for p in obj.parts], 1, seed=0)[0]
    path = tmp_path / "render.png"
    Image.fromarray(render_view(obj, view)).save(path)
    far = farther_view(path, 0.4)
    assert far.shape == (560, 560, 3)
    enc = ImageEncoder(ImageEncoderConfig()).eval()
    with torch.no_grad():
        ref = enc(preprocess(str(path)))
        plain = enc(preprocess(far))
        framed = enc(preprocess(far, frame=True))

    def cos(a, b):
        return float(torch.nn.functional.cosine_similarity(a.flatten(), b.flatten(), dim=0))
    assert cos(framed, ref) > cos(plain, ref) + 0.1
    assert torch.equal(preprocess(str(path)), preprocess(str(path), frame=False))


@pytest.mark.parametrize("frame", [True, False])
def test_the_generator_and_the_node_settings_pass_the_framing_choice_on(frame):
    from artformer_ros.params import NodeSettings
    from model.encoders.image import ImageInputError
    from model.pipeline.api import GenerationConfig, GenerationError
    from model.pipeline.generator import Generator

    assert GenerationConfig().frame_images is True
    cfg = NodeSettings.from_values({"frame_images": frame}).generation_config()
    assert cfg.frame_images is frame
    seen = []

    class _Image:   # stops the request right after the condition, recording how it was asked
        def condition(self, image, frame=False):
            seen.append(frame)
            raise ImageInputError("stop here")

    gen = Generator(cfg, articulation=None, shape=None, image_model=_Image())
    with pytest.raises(GenerationError, match="bad image: stop here"):
        gen.generate(image=np.zeros((8, 8, 3), np.uint8))
    assert seen == [frame]


def test_eval_refuses_a_farther_share_outside_0_1():
    from model.imaging.train import cli_main
    for bad in ("0", "1.5", "-0.3"):
        assert cli_main(["--eval", "model/weights/image_small.pt", "--farther", bad]) == 2
