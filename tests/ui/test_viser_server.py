"""The one place both apps get their viser server: it binds where asked, and the address it
gives a browser is one the browser can open (never the wildcard 0.0.0.0)."""

from __future__ import annotations

import warnings

from browser import free_port

from bbzide.ui.viser_server import open_server, page_url, quiet_closed_tab_updates


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


def test_an_update_to_a_closed_tab_warns_nobody_but_other_warnings_stay() -> None:
    # viser 1.1.1's words (infra/_async_message_buffer.py) for a message to a closed tab.
    closed_tab = ("Queued a GuiUpdateMessage on a closed connection (e.g. via a handle owned by a "
                  "disconnected client, or after the server stopped); it will never be delivered.")
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        quiet_closed_tab_updates()
        warnings.warn(closed_tab, UserWarning, stacklevel=1)
        warnings.warn("Queued a GuiUpdateMessage on a fine connection", UserWarning, stacklevel=1)
    assert [str(each.message) for each in shown] == [
        "Queued a GuiUpdateMessage on a fine connection"]
