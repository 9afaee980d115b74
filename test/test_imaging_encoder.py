"""EfficientNet-Lite0 condition encoder: real weights, token shapes, robust preprocessing."""
import numpy as np
import pytest
import torch

from model.encoders.image import (IMAGE_SIZE, ImageEncoder, ImageEncoderConfig, ImageInputError,
                                  get_image_encoder, preprocess, to_rgb_float)

torch.set_num_threads(1)

# ImageNet classes 281..285: tabby, tiger cat, Persian, Siamese, Egyptian cat
CAT_CLASSES = set(range(281, 286))


@pytest.fixture(scope="module")
def cat():
    from skimage import data
    return data.chelsea()          # (300, 451, 3) uint8, the bundled cat photo


def test_real_imagenet_weights_recognise_a_cat(cat):
    enc = get_image_encoder()
    logits = enc.classify(preprocess(cat))                       # (1, 1000)
    assert int(logits.argmax()) in CAT_CLASSES
    rand = ImageEncoder(ImageEncoderConfig(weights="none"))
    a, b = enc.net._conv_stem.weight, rand.net._conv_stem.weight
    assert not torch.allclose(a, b)
    # the pretrained network is confident on the photo, a random one is not
    assert float(logits.softmax(-1).max()) > 0.5
    assert float(rand.classify(preprocess(cat)).softmax(-1).max()) < 0.5


def test_condition_tokens_shape_and_mask(cat):
    enc = get_image_encoder()
    out = enc.encode(cat)
    tokens, mask = out.states, out.mask
    assert tokens.shape == (1, 49, 1280) and tokens.dtype == torch.float32
    assert mask.shape == (1, 49) and mask.dtype == torch.bool and bool(mask.all())
    assert torch.isfinite(tokens).all() and float(tokens.std()) > 0.1
    # the frozen encoder has no trainable parameters and is deterministic
    assert not any(p.requires_grad for p in enc.parameters())
    assert torch.equal(tokens, enc.encode(cat).states)
    batch = enc.encode([cat, cat[:, ::-1]])
    assert batch.states.shape == (2, 49, 1280) and batch.pooled.shape == (2, 1280)


def test_grey_rgba_odd_sizes_and_dtypes(cat):
    grey = cat.mean(axis=2).astype(np.uint8)                     # (H, W)
    x = preprocess(grey)
    assert x.shape == (1, 3, IMAGE_SIZE, IMAGE_SIZE)
    assert torch.equal(x[0, 0], x[0, 1]) and torch.equal(x[0, 1], x[0, 2])
    assert preprocess(grey[:, :, None]).shape == (1, 3, IMAGE_SIZE, IMAGE_SIZE)
    # opaque RGBA = RGB; fully transparent RGBA = the background colour
    opaque = np.concatenate([cat, np.full(cat.shape[:2] + (1,), 255, np.uint8)], axis=2)
    assert torch.allclose(preprocess(opaque), preprocess(cat))
    clear = opaque.copy()
    clear[..., 3] = 0
    rgb = to_rgb_float(clear, background=(0.2, 0.4, 0.6))
    assert np.allclose(rgb, [0.2, 0.4, 0.6], atol=1e-6)
    # uint8 and float [0, 1] give the same batch; odd sizes and aspect ratios are fine
    assert torch.allclose(preprocess(cat), preprocess(cat.astype(np.float32) / 255.0), atol=1e-5)
    for shape in [(17, 5, 3), (1, 1, 3), (500, 31, 4), (225, 223)]:
        arr = np.random.default_rng(0).integers(0, 255, shape, dtype=np.uint8)
        assert preprocess(arr).shape == (1, 3, IMAGE_SIZE, IMAGE_SIZE)
    assert preprocess([cat, grey]).shape == (2, 3, IMAGE_SIZE, IMAGE_SIZE)


def test_file_inputs_and_clear_errors(tmp_path, cat):
    from PIL import Image
    png = tmp_path / "cat.png"
    Image.fromarray(cat).save(png)
    assert torch.allclose(preprocess(str(png)), preprocess(cat))
    la = tmp_path / "grey_alpha.png"
    Image.fromarray(np.zeros((20, 30, 2), np.uint8), mode="LA").save(la)
    assert preprocess(la).shape == (1, 3, IMAGE_SIZE, IMAGE_SIZE)

    junk = tmp_path / "broken.png"
    junk.write_bytes(b"this is not an image at all")
    with pytest.raises(ImageInputError, match="cannot read"):
        get_image_encoder().encode(str(junk))
    with pytest.raises(ImageInputError, match="does not exist"):
        preprocess(tmp_path / "missing.jpg")
    with pytest.raises(ImageInputError, match="folder"):
        preprocess(tmp_path)
    with pytest.raises(ImageInputError, match="shape"):
        preprocess(np.zeros((8, 8, 7), np.uint8))
    with pytest.raises(ImageInputError, match="shape"):
        preprocess(np.zeros((2, 8, 8, 3), np.uint8))
    with pytest.raises(ImageInputError, match="NaN"):
        preprocess(np.full((8, 8, 3), np.nan, np.float32))
    with pytest.raises(ImageInputError, match="range"):
        preprocess(np.full((8, 8, 3), -1.0))
    with pytest.raises(ImageInputError, match="empty"):
        preprocess(np.zeros((0, 8, 3), np.uint8))
    with pytest.raises(ImageInputError):
        preprocess(None)


def test_fine_tuning_tail_is_trainable_and_trunk_frozen(cat):
    enc = ImageEncoder(ImageEncoderConfig(trainable_blocks=1))
    trainable = [p for p in enc.parameters() if p.requires_grad]
    assert trainable and len(trainable) == len(enc.tail_parameters())
    assert not any(p.requires_grad for p in enc.net._conv_stem.parameters())
    x = preprocess(cat)
    h = enc.trunk(x)                                             # (1, 192, 7, 7)
    assert h.shape == (1, 192, 7, 7) and not h.requires_grad
    enc.train()
    tokens = enc.tail(h)                                         # (1, 49, 1280)
    tokens.square().mean().backward()
    assert all(p.grad is not None for p in trainable)
    assert not enc.net.training                                  # BatchNorm stats stay frozen
    # the tail state dict round-trips into a fresh encoder
    with torch.no_grad():
        enc.net._conv_head.weight.mul_(0.5)
    state = enc.tail_state_dict()
    assert state and all(k.startswith(("_blocks.15.", "_conv_head.", "_bn1.")) for k in state)
    other = ImageEncoder(ImageEncoderConfig(trainable_blocks=1))
    other.load_tail_state_dict(state)
    assert torch.allclose(other(x), enc(x).detach(), atol=1e-5)


def test_multiscale_tokens_add_the_folded_fine_map(cat):
    import torch.nn.functional as F

    from model.encoders.image import FINE_CHANNELS, FINE_SPLIT, TOKEN_DIM
    base = get_image_encoder()
    ms = ImageEncoder(ImageEncoderConfig(multiscale=True))
    assert ms.dim == TOKEN_DIM + FINE_CHANNELS == 1728
    x = preprocess(cat)
    tok = ms(x)
    assert tok.shape == (1, 49, 1728)
    # the first 1280 channels are exactly the plain tokens
    assert torch.allclose(tok[..., :TOKEN_DIM], base(x), atol=1e-5)
    # the rest is the 14x14 block-10 map, each token the 2x2 cell under its 7x7 cell
    fine = ms.features_at(x, FINE_SPLIT)
    assert fine.shape == (1, 112, 14, 14)
    r, c = 3, 5
    cell = fine[0, :, 2 * r:2 * r + 2, 2 * c:2 * c + 2]                 # (112, 2, 2)
    assert torch.allclose(tok[0, r * 7 + c, TOKEN_DIM:], cell.reshape(112, 4).reshape(-1), atol=1e-5)
    assert torch.equal(F.pixel_unshuffle(fine, 2).flatten(2).transpose(1, 2), tok[..., TOKEN_DIM:])
    # split run (trunk cache + tail) gives the same tokens; the tail refuses a missing fine map
    h, f = ms.trunk_fine(x)
    assert torch.allclose(ms.tail(h, fine=f), tok)
    with pytest.raises(ValueError, match="14x14"):
        ms.tail(h)
    with pytest.raises(ValueError, match="multiscale"):
        ImageEncoder(ImageEncoderConfig(multiscale=True, trainable_blocks=6))


def test_larger_inputs_keep_same_padding_and_pool_to_the_token_grid(cat):
    """448-px inputs (a 2x-upsampled view): every convolution's static padding equals
    TensorFlow's 'same' padding at the size it really sees, the finer map is pooled to 7x7
    before the last block, the cached-trunk path gives the same tokens, and sizes that are
    no multiple of 224 are refused."""
    import math

    from efficientnet_lite_pytorch.utils import Conv2dStaticSamePadding
    enc = ImageEncoder(ImageEncoderConfig(image_size=448))
    seen = []

    def hook(mod, inp, _out):
        seen.append((mod, inp[0].shape[-1]))
    handles = [m.register_forward_hook(hook) for m in enc.net.modules()
               if isinstance(m, Conv2dStaticSamePadding)]
    x = preprocess(cat, 448)
    assert x.shape == (1, 3, 448, 448)
    tokens = enc(x)
    for h in handles:
        h.remove()
    assert len(seen) > 40
    for mod, size in seen:
        k, s = mod.weight.shape[-1], mod.stride[0]
        total = max((math.ceil(size / s) - 1) * s + k - size, 0)
        pad = mod.static_padding.padding if total else (0, 0, 0, 0)
        assert tuple(pad) == (total // 2, total - total // 2) * 2, (k, s, size, pad)
    assert tokens.shape == (1, 49, 1280)
    # the map entering block 15 is pooled to 7x7; the trainer's cached path agrees
    h = enc.features_at(x, 15)
    assert h.shape == (1, 192, 7, 7)
    assert torch.allclose(enc.tail(h, 15), tokens, atol=1e-5)
    full = enc.features_at(x, 14)
    assert full.shape[-1] == 14
    assert torch.allclose(enc.tail(full, 14), tokens, atol=1e-5)
    # the finer input gives other tokens than the same photo at 224 px
    assert not torch.allclose(tokens, get_image_encoder()(preprocess(cat)), atol=1e-2)
    assert enc.encode(cat).states.shape == (1, 49, 1280)
    for bad in (300, 112, 0):
        with pytest.raises(ValueError, match="multiple of 224"):
            ImageEncoder(ImageEncoderConfig(image_size=bad))
    with pytest.raises(ValueError, match="multiscale"):
        ImageEncoder(ImageEncoderConfig(image_size=448, multiscale=True))
