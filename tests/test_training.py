def test_learning_rate_is_constant_then_linear_to_zero():
    import pytest

    from retarget_lib.training.loop import learning_rate

    assert learning_rate(1e-3, 0, 100, None) == learning_rate(1e-3, 99, 100, None) == 1e-3
    assert learning_rate(1e-3, 49, 100, 0.5) == 1e-3
    assert learning_rate(1e-3, 50, 100, 0.5) == pytest.approx(1e-3)  # 50/50 left
    assert learning_rate(1e-3, 75, 100, 0.5) == pytest.approx(0.5e-3)  # halfway down the tail
    assert learning_rate(1e-3, 99, 100, 0.5) == pytest.approx(1e-3 / 50)  # last step: never 0
