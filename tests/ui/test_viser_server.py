"""The one place both apps get their viser server: it binds where asked, and the address it
gives a browser is one the browser can open (never the wildcard 0.0.0.0)."""

from __future__ import annotations

from browser import free_port

from bbzide.ui.viser_server import open_server, page_url


def test_open_server_binds_loopback_and_gives_its_url() -> None:
    port = free_port()
    server = open_server("127.0.0.1", port, "launch-token")
    try:
        assert server.get_host() == "127.0.0.1"
        assert page_url(server, "launch-token") == (
            f"http://127.0.0.1:{server.get_port()}/?token=launch-token"
        )
    finally:
        server.stop()


class _WildcardBound:
    """What a server started with ``--host 0.0.0.0`` reports (not started here: tests never
    listen beyond loopback)."""

    def get_host(self) -> str:
        return "0.0.0.0"

    def get_port(self) -> int:
        return 8123


def test_page_url_of_a_wildcard_bind_is_loopback() -> None:
    url = page_url(_WildcardBound(), "t0ken-123")  # type: ignore[arg-type]
    assert url == "http://127.0.0.1:8123/?token=t0ken-123"
