"""Passwords for an e-signature or an account change: a prompt on a terminal, or
`--password-stdin` (CONTRACT.md: the acting account's password on the first line of
standard input; a new account's initial password, where one is set, on the second).
Never an argument or an environment variable, which other users and logs can read."""

from __future__ import annotations

import getpass
import sys
from collections.abc import Iterator

from bench.app.register.store import RegisterError


class Passwords:
    """Hands out the passwords in the order CONTRACT.md gives them."""

    def __init__(self, from_stdin: bool) -> None:
        self._lines: Iterator[str] | None = None
        if from_stdin:
            self._lines = iter(sys.stdin.read().splitlines())

    def next(self, prompt: str) -> str:
        if self._lines is not None:
            try:
                value = next(self._lines)
            except StopIteration:
                raise RegisterError(f"--password-stdin: no line for {prompt.rstrip(': ')}") \
                    from None
            return value
        if not sys.stdin.isatty():
            raise RegisterError(f"{prompt.rstrip(': ')}: standard input is not a terminal; "
                                "give it with --password-stdin")
        return getpass.getpass(prompt)
