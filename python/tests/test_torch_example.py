"""python/examples/torch_autograd.py: the recorded run as a torch.autograd.Function passes
torch's gradcheck (its central differences). Skipped where torch is not installed (freeform
does not depend on it; CI does not install it)."""

import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

import torch_autograd  # noqa: E402


def test_the_simulation_function_passes_gradcheck():
    v = torch.tensor([0.25, -0.45, 0.15], dtype=torch.float64, requires_grad=True)
    mu = torch.tensor(0.5, dtype=torch.float64, requires_grad=True)
    # Steps solved to 1e-12 D; torch's step 1e-6 switches no contact, so its central
    # differences are good to about 1e-6 of the largest entries (the tolerances).
    assert torch.autograd.gradcheck(torch_autograd.Simulate.apply, (v, mu), eps=1e-6,
                                    atol=1e-7, rtol=1e-5)


def test_a_loss_through_the_function_descends():
    observed = torch.from_numpy(torch_autograd.record(torch_autograd.TRUE_V, 0.6)[2])
    v = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    mu = torch.tensor(0.3, dtype=torch.float64, requires_grad=True)
    loss = ((torch_autograd.Simulate.apply(v, mu) - observed) ** 2).mean()
    loss.backward()
    with torch.no_grad():
        step = 1e-3 / float(torch.cat([v.grad, mu.grad.reshape(1)]).norm())
        after = ((torch_autograd.Simulate.apply(v - step * v.grad, mu - step * mu.grad)
                  - observed) ** 2).mean()
    assert after < loss
