"""Benches drawn per sample: a dataset over benches drawn from a tolerance file, its benches
rebuilt from Python, and the deepinv physics and generator over them (the physics parts
skipped without torch and deepinv)."""

from __future__ import annotations

import numpy as np
import pytest

import spibench
from conftest import REPO, make_spec, paper_text


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """4 samples through 2 benches drawn from the paper bench's tolerance file."""
    d = tmp_path_factory.mktemp("drawn")
    bench = d / "bench.ron"
    bench.write_text(paper_text())
    spec = make_spec(d, bench, ["DoubleArm", "SecondaryComplementaryBalancing"], [0.1], samples=4,
                     shard=4)
    tol = REPO / "scenes" / "tolerances" / "paper_bench.ron"
    text = spec.read_text().replace(
        "    seed: 7,", f'    seed: 7,\n    benches: Tolerance(file: "{tol}", samples_per_bench: 2),')
    spec.write_text(text)
    spibench.make_dataset(spec, d / "out")
    return spibench.open_dataset(d / "out")


def test_drawn_benches_measure_as_the_dataset(drawn):
    assert drawn.benches == 2
    bench_of = np.asarray(drawn.array("bench")).astype(int)
    assert list(bench_of) == [0, 0, 1, 1]
    names = drawn.deviation_names
    objects = np.asarray(drawn.array("object"))
    meas = np.asarray(drawn.array("meas_double_arm_r0.1000"))
    for t in range(2):
        kernel, dev = drawn.drawn_bench(t)
        assert dev.shape == (len(names),)
        assert np.array_equal(dev, np.asarray(drawn.array("deviations"))[2 * t])
        acq = drawn.acquisition_on(kernel, "double_arm", 0.1)
        for s in (2 * t, 2 * t + 1):
            y = acq.forward(objects[s], noise=True, seed=[spibench.dataset_noise_seed(drawn.seed, s)])
            assert np.array_equal(y, meas[s]), (t, s)
    with pytest.raises(spibench.InputError, match="2 benches"):
        drawn.drawn_bench(2)
    with pytest.raises(spibench.InputError, match="drawn benches"):
        drawn.torch_dataset("double_arm", 0.1)


def test_a_nominal_dataset_has_one_bench(dataset):
    ds, _ = dataset
    assert ds.benches == 1 and ds.deviation_names == []
    with pytest.raises(spibench.InputError, match="nominal bench"):
        ds.drawn_bench(0)


def test_physics_and_generator_over_drawn_benches(drawn):
    torch = pytest.importorskip("torch")
    pytest.importorskip("deepinv")
    from spibench.deepinv import BenchGenerator, TracedBenches

    kernels = [drawn.drawn_bench(t)[0] for t in range(drawn.benches)]
    acqs = [drawn.acquisition_on(k, "double_arm", 0.1) for k in kernels]
    phys = TracedBenches(acqs, kernels, noise="bench", seed=drawn.seed, dtype=torch.float64)
    assert float(phys.scale) == pytest.approx(acqs[0].operator_norm(), rel=1e-12)
    x = torch.from_numpy(np.array(drawn.array("object"))).unsqueeze(1)
    bench = torch.from_numpy(np.array(drawn.array("bench")).astype(np.int64))
    # Each sample through its own bench, as each bench's operator alone gives it.
    y = phys.A(x, bench=bench)
    for s in range(4):
        want = acqs[int(bench[s])].apply(x[s, 0].numpy()) / float(phys.scale)
        assert np.allclose(y[s].numpy(), want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    # The adjoint of the per-sample operator.
    v = torch.randn_like(y)
    lhs = (y * v).sum()
    rhs = (phys.A_adjoint(v, bench=bench) * x).sum()
    assert float(abs(lhs - rhs) / abs(lhs)) < 1e-10
    # The bench's own simulation of the batch is the dataset's measurement (record seeds of
    # samples 0…3 of its seed), offset of each sample's bench removed.
    meas = torch.from_numpy(np.array(drawn.array("meas_double_arm_r0.1000")))
    got = phys(x, bench=bench)
    assert torch.allclose(got, phys.remove_offset(meas, bench=bench), rtol=0, atol=1e-12)
    # The generator: reproducible draws of indices in range, on its own generator.
    gen = BenchGenerator(phys.benches, seed=3)
    a = gen.step(batch_size=64)["bench"]
    gen.reset_rng()
    assert torch.equal(a, gen.step(batch_size=64)["bench"])
    assert a.dtype == torch.int64 and set(a.tolist()) == {0, 1}
    phys.update(**gen.step(batch_size=4))
    assert phys.bench.shape == (4,)
    assert phys.A(x).shape == (4, acqs[0].measurements)
    with pytest.raises(spibench.InputError, match="indices"):
        phys.update(bench=torch.tensor([2]))
