"""meshcat's server for `play`, reachable from this machine only and tied to its parent's life.

meshcat 0.3.2 serves its page with tornado on every network interface and runs on in its own
session after its parent dies. Run as ``python -m redundancy.viz.server``, this is the same
server (`meshcat.servers.zmqserver`) with its web and ZeroMQ sockets bound to 127.0.0.1, and, on
Linux, a parent-death signal: the kernel sends it SIGTERM when the process that started it ends,
however it ends (SIGKILL included). It prints meshcat's ``zmq_url=`` and ``web_url=`` lines.

``python -m redundancy.viz.server PARENT_PID [ADDRESS]``: the web page is served on ADDRESS
(default 127.0.0.1) when asked for deliberately; the ZeroMQ socket stays on 127.0.0.1.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

LOCALHOST = "127.0.0.1"
PR_SET_PDEATHSIG = 1  # prctl option, <linux/prctl.h>


def die_with_parent(parent: int) -> None:
    """Ask the kernel for SIGTERM when the parent ends (Linux); end now if it already has."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:
        sys.exit(0)


def main() -> None:
    die_with_parent(int(sys.argv[1]))
    web = sys.argv[2] if len(sys.argv) > 2 else LOCALHOST
    import tornado.web
    from meshcat.servers import zmqserver

    listen = tornado.web.Application.listen

    def bound(self, port, address=None, **options):
        return listen(self, port, web, **options)

    tornado.web.Application.listen = bound  # type: ignore[method-assign]
    sys.argv = sys.argv[:1]
    zmqserver.main()


if __name__ == "__main__":
    main()
