"""The viser server both apps stand on (the live IDE and the replay), set up one way.

Both pages look alike on purpose — a user who records in the IDE and replays the file finds
the same panels in the same places — so the theme, the docked control panel and the page
address live here, once. The server binds where the caller says (127.0.0.1 unless the user
passed ``--host``; viser's own default, 0.0.0.0, is never used implicitly).
"""

from __future__ import annotations

import viser


def open_server(host: str, port: int) -> viser.ViserServer:
    """A viser server with the bbzide theme and the control panel docked on the right."""
    server = viser.ViserServer(host=host, port=port, verbose=False)
    server.gui.configure_theme(control_width="large", show_share_button=False, dark_mode=False)
    # Docked, not floating: the 3D view then spans only the free area between the panels, so
    # the camera's centre (where the swarm is framed) is visible, not behind the controls.
    server.gui.main_panel.dock_right()
    return server


def page_url(server: viser.ViserServer) -> str:
    """The address to open in a browser (a wildcard bind is reached through 127.0.0.1)."""
    host = server.get_host()
    return f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{server.get_port()}/"
