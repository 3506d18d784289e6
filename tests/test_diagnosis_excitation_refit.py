"""The excitation diagnosis's second pass: a baseline re-fitted into a better basin from a
hypothesis's factors leaves every hypothesis's fit started from the old baseline, so each is
fitted again from the new one and the better of its two fits kept."""
from __future__ import annotations

from types import SimpleNamespace

from calibration.diagnosis.excitation import diagnose as stage


def test_every_hypothesis_is_fitted_again_from_the_re_fitted_baseline_and_its_better_fit_kept(monkeypatch):
    said, started_from = [], []
    new_base = SimpleNamespace(name="new")

    def fitter(name, error_again):
        def fit(ctx, base):
            started_from.append((name, base.name))
            return [SimpleNamespace(name=name, train_error=error_again)]
        return fit

    # one hypothesis fits far better from the new baseline, the other worse than before
    monkeypatch.setattr(stage, "EXTENSIONS", {"a": SimpleNamespace(fit=fitter("a", 3.0)),
                                              "b": SimpleNamespace(fit=fitter("b", 90.0))})
    ctx = SimpleNamespace(sensors=("s1", "s2", "s3"), say=said.append)
    before = {"a": SimpleNamespace(name="a", train_error=600.0), "b": SimpleNamespace(name="b", train_error=60.0)}
    after = stage._refit_hypotheses(ctx, new_base, before)
    assert started_from == [("a", "new"), ("b", "new")]
    assert after["a"].train_error == 3.0 and after["b"] is before["b"]
    assert len(said) == 2 and "training error 1.00 against 200.00" in said[0]
