"""meshcat's server for `play`, reachable from this machine only and tied to its parent's life.

meshcat 0.3.2's own server serves its page on every network interface and runs on in its own
session after its parent dies. Run as ``python -m redundancy.viz.server PARENT_PID ADDRESS``,
this is the same server (meshcat's `ZMQWebSocketBridge`) with its web page served on ADDRESS
(127.0.0.1 unless asked deliberately) and its ZeroMQ socket on 127.0.0.1, and which dies with the
process that started it, however that ends (`die_with_parent`). Its page (``web_url``) is the
HTML it reads from its standard input, the playback's own, in place of meshcat's. It prints
meshcat's ``zmq_url=`` and ``web_url=`` lines.
"""

from __future__ import annotations

import sys
from functools import partial
from types import SimpleNamespace

from redundancy.study.background import die_with_parent

LOCALHOST = "127.0.0.1"


def main() -> None:
    die_with_parent(int(sys.argv[1]))
    web, page = sys.argv[2], sys.stdin.buffer.read()  # UTF-8
    import tornado.web
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class Page(tornado.web.RequestHandler):
        def get(self):
            self.finish(page)

    class Bridge(ZMQWebSocketBridge):
        """meshcat's server, its web application listening on ``web`` alone, its page
        ``page``."""

        def make_app(self):
            application = super().make_app()
            # a host's rules come before the application's own, so this one page replaces
            # meshcat's at web_url while its scripts and its socket stay as they are
            application.add_handlers(r".*", [(r"/static/", Page)])
            # all meshcat's server asks of its application: to listen, here on ``web`` alone
            return SimpleNamespace(listen=partial(application.listen, address=web))

    bridge = Bridge(host=LOCALHOST)
    print(f"zmq_url={bridge.zmq_url}\nweb_url={bridge.web_url}", flush=True)
    bridge.run()


if __name__ == "__main__":
    main()
