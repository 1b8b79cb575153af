"""The TF-MOT strategies' torch pieces that stand in for torch's own: equal to them, faster."""
import pytest
import torch

from pilotlab.strategies.mot_torch import Clusters, FakeQuantPerTensor, _memory_order


def _activation(shape, channels_last: bool, scale: float) -> torch.Tensor:
    torch.manual_seed(0)
    x = torch.randn(*shape) * 200 * scale                     # well past both ends of the int8 range
    flat = torch.arange(-300, 300, dtype=torch.float32) + 0.5  # exact ties: rounded half to even
    x.view(-1)[:flat.numel()] = flat * scale
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


@pytest.mark.parametrize("scale,zero", [(0.013, -128), (0.0234, -3), (1 / 255, 0), (0.5, 10)])
@pytest.mark.parametrize("shape,channels_last", [((4, 6, 9, 11), True), ((4, 6, 9, 11), False), ((8, 100), False)])
def test_fake_quant_per_tensor_equals_torchs_values_gradient_and_layout(scale, zero, shape, channels_last):
    x = _activation(shape, channels_last, scale)
    ours, theirs = x.clone().requires_grad_(), x.clone().requires_grad_()
    out_ours = FakeQuantPerTensor.apply(ours, scale, zero, -128, 127)
    out_theirs = torch.fake_quantize_per_tensor_affine(theirs, scale, zero, -128, 127)
    grad = torch.randn(shape)
    out_ours.backward(grad)
    out_theirs.backward(grad)
    assert torch.equal(out_ours, out_theirs)
    assert torch.equal(ours.grad, theirs.grad)
    assert 0 < int((ours.grad == 0).sum()) < ours.numel()     # some values were clamped, some not
    assert out_ours.is_contiguous(memory_format=torch.channels_last) == channels_last


def test_memory_order_is_a_view_of_the_same_elements():
    x = torch.randn(2, 3, 4, 5).contiguous(memory_format=torch.channels_last)
    view = _memory_order(x)
    assert view.is_contiguous() and view.data_ptr() == x.data_ptr()
    assert torch.equal(torch.aminmax(view).min, x.min()) and torch.equal(torch.aminmax(view).max, x.max())
    plain = torch.randn(2, 3)
    assert _memory_order(plain) is plain


def test_clustered_weight_keeps_the_layout_the_convolution_trains_in():
    weight = torch.randn(4, 3, 5, 5).contiguous(memory_format=torch.channels_last)
    index = torch.randint(0, 3, (weight.numel(),))
    clustered = Clusters(torch.tensor([-1.0, 0.5, 2.0]), index)(weight)
    assert clustered.is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(clustered.contiguous().flatten(), torch.tensor([-1.0, 0.5, 2.0])[index])
    assert Clusters(torch.tensor([1.0]), torch.zeros(6, dtype=torch.long))(torch.randn(2, 3)).is_contiguous()
