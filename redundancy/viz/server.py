"""meshcat's server for `play`, reachable from this machine only and tied to its parent's life.

meshcat 0.3.2's own server serves its page on every network interface and runs on in its own
session after its parent dies. Run as ``python -m redundancy.viz.server PARENT_PID [ADDRESS]``,
this is the same server (meshcat's `ZMQWebSocketBridge`) with its web page served on ADDRESS
(127.0.0.1 unless asked deliberately) and its ZeroMQ socket on 127.0.0.1, and which dies with the
process that started it, however that ends (`die_with_parent`). It prints meshcat's ``zmq_url=``
and ``web_url=`` lines.

Its page (``web_url``) is the playback's own, titled and with its gauges and controls, once the
parent has sent it as a `PAGE` command on the ZeroMQ socket; until then, meshcat's.
"""

from __future__ import annotations

import sys

from redundancy.study.background import die_with_parent

LOCALHOST = "127.0.0.1"
PAGE = b"page"  # ZeroMQ command: [PAGE, html] makes html the page served at web_url


class Listening:
    """A tornado application that listens on one address: all meshcat's server asks of it."""

    def __init__(self, application, address: str):
        self.application, self.address = application, address

    def listen(self, port: int, **options):
        return self.application.listen(port, self.address, **options)


def main() -> None:
    die_with_parent(int(sys.argv[1]))
    web = sys.argv[2] if len(sys.argv) > 2 else LOCALHOST
    import tornado.web
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class Page(tornado.web.RequestHandler):
        """The playback's page, where the parent has sent one; else meshcat's."""

        def initialize(self, bridge):
            self.bridge = bridge

        def get(self):
            if self.bridge.page is None:
                self.redirect("index.html")
            else:
                self.finish(self.bridge.page)

    class Bridge(ZMQWebSocketBridge):
        """meshcat's server, its web application listening on ``web`` alone, its page the one
        the parent sends."""

        page: bytes | None = None

        def make_app(self):
            application = super().make_app()
            # a host rule is matched before the application's own rules, so this one page
            # replaces meshcat's at web_url while its scripts and socket stay as they are
            application.add_handlers(r".*", [(r"/static/", Page, {"bridge": self})])
            return Listening(application, web)

        def handle_zmq(self, frames):
            if frames[0] == PAGE:
                self.page = frames[1]
                self.zmq_socket.send(b"ok")
            else:
                super().handle_zmq(frames)

    bridge = Bridge(host=LOCALHOST)
    print(f"zmq_url={bridge.zmq_url}\nweb_url={bridge.web_url}", flush=True)
    bridge.run()


if __name__ == "__main__":
    main()
