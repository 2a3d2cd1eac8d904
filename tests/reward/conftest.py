"""The reward tests reuse the closed-loop tests' tiny trained checkpoints (200-policy cycles)."""

from tests.drive.conftest import TINY_POLICIES, tiny_runs  # noqa: F401
