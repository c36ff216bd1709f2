"""A warm pytest for mutmut on a busy machine: imports numpy, scipy, hypothesis and pytest once,
then runs each request in a fresh fork, so each mutant costs only its tests.

    python tools/pytest_server.py SOCKET TESTFILE &      # from the tree being mutated
    mutmut run ... --runner "python tools/pytest_client.py SOCKET"

The fork imports the project's modules itself (the server never does), so it sees the mutant.
Hypothesis runs 20 examples per property (profile "mutmut") instead of 100.
"""

from __future__ import annotations

import os
import socket
import sys

import _pytest.assertion.rewrite
import _pytest.python  # noqa: F401
import hypothesis
import hypothesis.extra.pytestplugin
import numpy  # noqa: F401
import pytest
import scipy.signal
import scipy.stats  # noqa: F401

try:  # the pytest-qt plugin loads Qt at every start
    import pytestqt.plugin  # noqa: F401
except ImportError:
    pass

hypothesis.settings.register_profile("mutmut", max_examples=20, deadline=None)


def main() -> None:
    path, testfile = sys.argv[1], sys.argv[2]
    if os.path.exists(path):
        os.unlink(path)
    server = socket.socket(socket.AF_UNIX)
    server.bind(path)
    server.listen(1)
    while True:
        conn, _ = server.accept()
        conn.recv(16)
        pid = os.fork()
        if pid == 0:
            server.close()
            conn.close()
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            args = ["-x", "-q", "-p", "no:cacheprovider", "--hypothesis-profile=mutmut", testfile]
            os._exit(int(pytest.main(args)))
        _, status = os.waitpid(pid, 0)
        code = os.waitstatus_to_exitcode(status)
        conn.sendall(str(code).encode())
        conn.close()


if __name__ == "__main__":
    main()
