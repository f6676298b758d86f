"""The network guard in every Python subprocess a test starts.

The test plugin (tests/netguard.py) puts this directory first on PYTHONPATH, so any
interpreter the tests start (`bench run`, a twin server, `python -c`, an xdist worker)
imports this file at start-up. With RATEBENCH_NETGUARD_LOG set it installs the same guard
as the test process and appends each refused attempt to that file, which the test reads
at its teardown: the subprocess may have exited long before, or have swallowed the error.

This file shadows any other sitecustomize (Debian's installs apport's hook), so that one
is run after the guard, as it would have been without us.
"""

from __future__ import annotations

import importlib.util
import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))


def _guard() -> None:
    if not os.environ.get("RATEBENCH_NETGUARD_LOG"):
        return
    if _HERE not in sys.path:
        sys.path.insert(0, _HERE)
    import netguard_core

    netguard_core.install()
    netguard_core.log_to_file(True)


def _next_sitecustomize() -> None:
    for entry in sys.path:
        if not entry or os.path.abspath(entry) == _HERE:
            continue
        candidate = os.path.join(entry, "sitecustomize.py")
        if os.path.isfile(candidate):
            spec = importlib.util.spec_from_file_location("_sitecustomize_after_netguard",
                                                          candidate)
            if spec is not None and spec.loader is not None:
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
            return


_guard()
_next_sitecustomize()
