"""The register's password hashes (issue 53): argon2id with RFC 9106's low-memory
parameters, the hash recording them; the suite's own registers hash with cheaper ones
(tests/conftest.py `cheap_password_hashes`), which this file checks are only the suite's."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest


def test_the_register_hashes_with_rfc_9106_low_memory(
        cheap_password_hashes: Callable[[], Any], monkeypatch: pytest.MonkeyPatch) -> None:
    from argon2 import extract_parameters
    from argon2.profiles import RFC_9106_LOW_MEMORY

    from bench.app.register import model

    monkeypatch.setattr(model, "_hasher", cheap_password_hashes)   # the register's own
    stored = model.hash_password("petrov-pass-1", "P. Petrov")
    assert stored.startswith("$argon2id$v=19$m=65536,t=3,p=4$")
    assert extract_parameters(stored) == RFC_9106_LOW_MEMORY
    assert model._verify(stored, "petrov-pass-1")
    assert not model._verify(stored, "petrov-pass-2")


def test_the_suites_cheap_hashes_are_argon2id_and_checked_as_any(
        cheap_password_hashes: Callable[[], Any]) -> None:
    """A cheap hash is still argon2id and checked by the register's own hasher (its
    parameters are in the hash), and a wrong password is still refused."""
    from argon2 import extract_parameters

    from bench.app.register import model
    from tests.conftest import CHEAP_ARGON2

    stored = model.hash_password("petrov-pass-1", "P. Petrov")
    params = extract_parameters(stored)
    assert (params.time_cost, params.memory_cost, params.parallelism) == (
        CHEAP_ARGON2["time_cost"], CHEAP_ARGON2["memory_cost"], CHEAP_ARGON2["parallelism"])
    assert stored.startswith("$argon2id$")
    shipped = cheap_password_hashes()
    assert shipped.verify(stored, "petrov-pass-1")
    assert not model._verify(stored, "not-the-password")
