"""Session-wide set-up: the compiled kernels are compiled (or loaded) once before any test, so that no
test's captured output holds ``warm_up``'s one-time compile lines on a cold cache."""

import pytest


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels():
    import sim.sensors.raycast  # noqa: F401 - registers the caster's warm-up
    from tracker.warmup import warm_up

    warm_up()
