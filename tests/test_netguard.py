"""The network guard (tests/netguard.py) proved on inner pytest runs (pytester): a test
whose code reaches outside the machine fails at teardown even when the attempt's error was
caught, in the test process, through a multicast join and from a subprocess; loopback
passes untouched.

Each inner run is a fresh `python -m pytest` in pytester's directory with the plugin named
by `-p`, not this project's addopts or conftest, so what it reports is the plugin's alone.
192.0.2.1 (TEST-NET-1, RFC 5737) is never reached: the guard raises before the system
call, which the inner tests check by the error they catch (a PermissionError naming the
guard, not the ENETUNREACH or timeout a real attempt would give).
"""

from __future__ import annotations

import os
import socket
import sys
import textwrap

import pytest

from tests.conftest import ROOT
from tests.netguard import core

pytest_plugins = ["pytester"]

#: caught inside the inner test, so only the guard's teardown can fail it
CONNECT = """
    import socket
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.settimeout(2)
    try:
        s.connect(("192.0.2.1", 9))
        caught = None
    except OSError as e:
        caught = e
    finally:
        s.close()
    assert isinstance(caught, PermissionError) and "network guard" in str(caught), caught
"""


def _run(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, source: str,
         *args: str) -> pytest.RunResult:
    """`pytest -p tests.netguard` on one inner test file, in its own process."""
    pytester.makeini("[pytest]\n")      # rootdir here: no addopts of the project's
    pytester.makepyfile(test_inner=textwrap.dedent(source))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p))
    return pytester.runpytest_subprocess("-p", "tests.netguard", "-p", "no:cacheprovider",
                                         *(args or ("-p", "no:xdist")), timeout=120)


def _body(code: str) -> str:
    return textwrap.indent(textwrap.dedent(code), "    ")


def test_a_caught_connect_fails_the_test_at_teardown(pytester: pytest.Pytester,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    r = _run(pytester, monkeypatch, f"def test_swallows():\n{_body(CONNECT)}")
    r.assert_outcomes(passed=1, errors=1)        # the body passed, the teardown did not
    out = r.stdout.str()
    assert "ERROR at teardown of test_swallows" in out
    assert "connect to 192.0.2.1:9 (this process)" in out
    assert "network guard: 1 refused attempts" in out
    assert r.ret == pytest.ExitCode.TESTS_FAILED


def test_a_host_name_is_refused_unresolved(pytester: pytest.Pytester,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """create_connection resolves first: the lookup itself is refused (no DNS query)."""
    r = _run(pytester, monkeypatch, """
        import socket

        def test_resolves():
            try:
                socket.create_connection(("example.com", 80), timeout=2).close()
            except OSError as e:
                assert isinstance(e, PermissionError) and "network guard" in str(e), e
    """)
    r.assert_outcomes(passed=1, errors=1)
    assert "getaddrinfo to example.com:80 (this process)" in r.stdout.str()


def _failed_at_teardown(r: pytest.RunResult, attempt: str) -> None:
    """The inner test's body passed, its teardown failed naming the one attempt."""
    r.assert_outcomes(passed=1, errors=1)
    out = r.stdout.str()
    assert attempt in out
    assert "network guard: 1 refused attempts" in out


def test_a_multicast_join_fails_the_test(pytester: pytest.Pytester,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    r = _run(pytester, monkeypatch, """
        import socket

        def test_joins():
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            mreq = socket.inet_aton("239.1.2.3") + socket.inet_aton("127.0.0.1")
            try:
                s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
            except OSError as e:
                assert "network guard" in str(e)
            finally:
                s.close()
    """)
    _failed_at_teardown(r, "setsockopt to multicast group 239.1.2.3")


def test_a_subprocess_attempt_fails_the_test_that_started_it(
        pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> None:
    child = textwrap.dedent(CONNECT) + "print('child caught:', caught)\n"
    r = _run(pytester, monkeypatch, f"""
        import subprocess, sys

        def test_child():
            out = subprocess.run([sys.executable, "-c", {child!r}], capture_output=True,
                                 text=True, timeout=60)
            assert out.returncode == 0, out.stderr
            assert "child caught: [Errno 13] network guard" in out.stdout, out.stdout
    """)
    _failed_at_teardown(r, "connect to 192.0.2.1:9 (subprocess")


def test_an_attempt_outside_any_test_fails_the_session(
        pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> None:
    r = _run(pytester, monkeypatch, f"""
        import subprocess, sys
        import pytest

        @pytest.fixture(scope="module")
        def server():
            subprocess.run([sys.executable, "-c", {textwrap.dedent(CONNECT)!r}], timeout=60)

        def test_uses_it(server):
            pass
    """)
    r.assert_outcomes(passed=1)
    out = r.stdout.str()
    assert "1 refused attempt(s) outside any test" in out and "192.0.2.1:9" in out
    assert r.ret == pytest.ExitCode.TESTS_FAILED


def test_xdist_workers_share_the_log_and_the_summary(
        pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> None:
    """Under `-n 2` each test fails for its own attempt (one in a worker, one in a
    subprocess of a worker) and the controller's summary counts both."""
    child = textwrap.dedent(CONNECT)
    r = _run(pytester, monkeypatch, (
        "import subprocess, sys\n\n"
        f"def test_in_worker():\n{_body(CONNECT)}\n"
        "def test_in_subprocess():\n"
        f"    subprocess.run([sys.executable, '-c', {child!r}], check=True, timeout=60)\n"),
        "-n", "2")
    r.assert_outcomes(passed=2, errors=2)
    assert "network guard: 2 refused attempts" in r.stdout.str()


def _has_ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6) as s:
            s.bind(("::1", 0))
    except OSError:
        return False
    return True


LOOPBACK = """
    import socket, subprocess, sys
    import pytest

    CASES = [__CASES__]
    CHILD = ("import socket, sys; s = socket.create_connection(('127.0.0.1', "
             "int(sys.argv[1])), timeout=5); s.close()")

    @pytest.mark.parametrize("family,host,bind_family,bind_host", CASES)
    def test_tcp(family, host, bind_family, bind_host):
        with socket.socket(bind_family) as srv:
            srv.bind((bind_host, 0))
            srv.listen()
            port = srv.getsockname()[1]
            with socket.socket(family) as a, socket.socket(family) as b:
                a.settimeout(5)
                b.settimeout(5)
                a.connect((host, port))
                assert b.connect_ex((host, port)) == 0
            if bind_family == socket.AF_INET:
                subprocess.run([sys.executable, "-c", CHILD, str(port)], check=True,
                               timeout=60)

    def test_udp():
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as r, \\
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            r.bind(("127.0.0.1", 0))
            s.sendto(b"x", r.getsockname())
            s.sendto(b"y", 0, r.getsockname())
            s.sendmsg([b"z"], [], 0, r.getsockname())
            assert [r.recv(1) for _ in range(3)] == [b"x", b"y", b"z"]

    def test_unix_socket():
        import os, tempfile   # a short path: AF_UNIX allows about 100 bytes
        with tempfile.TemporaryDirectory() as d, socket.socket(socket.AF_UNIX) as srv, \\
                socket.socket(socket.AF_UNIX) as c:
            srv.bind(os.path.join(d, "s"))
            srv.listen()
            c.connect(os.path.join(d, "s"))
"""


def test_loopback_passes_with_nothing_refused(pytester: pytest.Pytester,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """127.0.0.1, localhost and, where the machine has IPv6 loopback, ::1 and the
    IPv4-mapped ::ffff:127.0.0.1: connected in the test and in a subprocess, sent to over
    UDP; an AF_UNIX socket is not checked at all."""
    cases = ["(socket.AF_INET, '127.0.0.1', socket.AF_INET, '127.0.0.1')",
             "(socket.AF_INET, 'localhost', socket.AF_INET, '127.0.0.1')"]
    if _has_ipv6_loopback():
        cases += ["(socket.AF_INET6, '::1', socket.AF_INET6, '::1')",
                  "(socket.AF_INET6, '::ffff:127.0.0.1', socket.AF_INET, '127.0.0.1')"]
    r = _run(pytester, monkeypatch, LOOPBACK.replace("__CASES__", ", ".join(cases)))
    r.assert_outcomes(passed=len(cases) + 2)
    assert "network guard: 0 refused attempts" in r.stdout.str()
    assert r.ret == pytest.ExitCode.OK


@pytest.mark.parametrize("host", ["127.0.0.1", "127.8.9.10", "::1", "::ffff:127.0.0.1",
                                  "localhost", "LOCALHOST"])
def test_local_hosts(host: str) -> None:
    assert core.is_local_host(host)
    assert core.refused_address(socket.AF_INET6, (host, 1)) is None


@pytest.mark.parametrize("host,printed", [
    ("192.0.2.1", "192.0.2.1:9"), ("0.0.0.0", "0.0.0.0:9"), ("", ":9"),
    ("::ffff:192.0.2.1", "[::ffff:192.0.2.1]:9"), ("2001:db8::1", "[2001:db8::1]:9"),
    ("example.com", "example.com:9"), ("localhost.example.com", "localhost.example.com:9"),
    ("239.1.2.3", "239.1.2.3:9"), ("<broadcast>", "<broadcast>:9"),
])
def test_refused_hosts(host: str, printed: str) -> None:
    assert core.refused_address(socket.AF_INET, (host, 9)) == printed


@pytest.mark.parametrize("host,refused", [
    ("example.com", "example.com:80"), ("localhost", None), ("192.0.2.1", None),
    ("::1", None), (None, None), ("", None), (b"example.com", "example.com:80"),
])
def test_lookups(host: str | bytes | None, refused: str | None) -> None:
    assert core.refused_lookup(host, 80) == refused


def test_other_families_are_not_checked() -> None:
    assert core.refused_address(socket.AF_UNIX, "/tmp/x") is None
    assert core.refused_address(socket.AF_INET6, ("::1", 9, 0, 0)) is None


def test_multicast_options() -> None:
    v4 = socket.inet_aton("224.0.0.251") + socket.inet_aton("0.0.0.0")
    assert core.multicast_group(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, v4) == \
        "multicast group 224.0.0.251"
    v6 = socket.inet_pton(socket.AF_INET6, "ff02::fb") + (0).to_bytes(4, sys.byteorder)
    assert core.multicast_group(socket.IPPROTO_IPV6, socket.IPV6_JOIN_GROUP, v6) == \
        "multicast group ff02::fb"
    assert core.multicast_group(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1) is None
    assert core.multicast_group(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1) is None
