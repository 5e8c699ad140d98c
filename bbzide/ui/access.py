"""Who may use a running IDE: a per-launch secret token, the page's own origin, a known host name.

The IDE edits a file on the user's disk and runs their program, so any web page the user visits
must not reach it, although every page can send requests to 127.0.0.1. The rules follow
Jupyter's; each request (every HTTP route and every websocket handshake) passes all four:

1. **Host**: the `Host` header names this server: a loopback name (localhost, 127.0.0.1, [::1]),
   the address it was bound to, the address the request actually arrived on (with
   `--host 0.0.0.0`, any of the machine's own addresses), or the machine's own host name; and
   the port is the one it listens on. A page whose domain re-resolves to 127.0.0.1
   (DNS rebinding) sends its own domain here and is refused.
2. **Origin**: when the browser says where the request comes from, it is the IDE's own page,
   `http://<Host>`. Browsers send `Origin` on every websocket handshake and every request that
   writes, so another site's page (or another port on 127.0.0.1) is refused.
3. **Sec-Fetch-Site**: when present, `same-origin` or `none` (the user opened the address
   themselves), or a top-level navigation (a link followed to the IDE: the page that had the
   link is gone and cannot read anything). It refuses the reads `Origin` does not cover: a
   `<script src>`, `<img src>` or `<iframe>` from another port of the same machine, which is
   "same-site" and would carry the cookie.
4. **Token**: the request carries the launch's secret, as `?token=` in the address (the link
   printed in the terminal), as the `bbzide-token-<port>` cookie that the first answer to such a
   link sets (HttpOnly, SameSite=Strict: pages never read it and other sites never send it), or
   as an `Authorization: token <secret>` header for scripts. The cookie's name carries the port
   because cookies ignore ports: two IDEs on one machine keep their own.

`check_request` is pure (headers in, verdict out) so that every rule is unit-tested without a
server; `bbzide.ui.viser_server` applies it to the one port the IDE listens on.
"""

from __future__ import annotations

import hmac
import ipaddress
import os
import re
import secrets
import socket
from collections.abc import Mapping
from dataclasses import dataclass, field
from http import HTTPStatus
from urllib.parse import parse_qs

#: Environment variable holding a fixed token for scripted use (the `--token` option wins).
TOKEN_ENV = "BBZIDE_TOKEN"
#: Bytes of randomness in a launch's token: 32 bytes (256 bits) as `secrets` recommends; it
#: reads as 43 URL-safe characters.
TOKEN_BYTES = 32
#: A token given by the user goes unescaped into a URL and a cookie: URL-safe characters only,
#: and at least 8 of them so that it is not guessed by trying (a launch's own token has 43).
TOKEN_PATTERN = re.compile(r"[A-Za-z0-9._~-]{8,}")
#: Names of the loopback interface that a browser on this machine may put in `Host`.
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
#: Bind addresses meaning "every interface".
WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::"})
#: `Sec-Fetch-Site` values of a request the IDE's own page (or the user, typing the address)
#: made; "same-site" is another port of the same machine, "cross-site" any other site.
OWN_FETCH_SITES = frozenset({"same-origin", "none"})


class TokenError(ValueError):
    """A token the user gave that cannot be used (empty, too short, not URL-safe)."""


def new_token() -> str:
    return secrets.token_urlsafe(TOKEN_BYTES)


def choose_token(given: str | None, environ: Mapping[str, str] = os.environ) -> str:
    """The token of this launch: `--token`, else $BBZIDE_TOKEN, else a fresh random one."""
    token = given if given is not None else environ.get(TOKEN_ENV)
    if token is None:
        return new_token()
    source = "--token" if given is not None else f"${TOKEN_ENV}"
    if not TOKEN_PATTERN.fullmatch(token):
        raise TokenError(f"{source} must be at least 8 characters among A-Z a-z 0-9 . _ ~ - "
                         f"(it goes into the page's address and a cookie), got {token!r}")
    return token


def cookie_name(port: int) -> str:
    return f"bbzide-token-{port}"


@dataclass(frozen=True)
class Verdict:
    """The answer to one request: allowed (status None) or refused with a status and a reason."""

    status: HTTPStatus | None = None
    reason: str = ""
    #: The token came in the address: the answer sets the cookie so later requests carry it.
    set_cookie: bool = False

    @property
    def allowed(self) -> bool:
        return self.status is None


@dataclass(frozen=True)
class AccessPolicy:
    """The token and addresses one server accepts."""

    token: str
    bound_host: str = "127.0.0.1"
    #: Extra host names accepted in `Host` (the machine's names when bound on every interface).
    host_names: frozenset[str] = field(default_factory=frozenset)

    @classmethod
    def for_bind(cls, token: str, bound_host: str) -> AccessPolicy:
        names: set[str] = set()
        if bound_host in WILDCARD_HOSTS:  # reached from other machines by the host's name
            names = {socket.gethostname().lower(), socket.getfqdn().lower()}
        return cls(token, bound_host.lower(), frozenset(names))

    def cookie_header(self, port: int) -> str:
        return (f"{cookie_name(port)}={self.token}; Path=/; HttpOnly; SameSite=Strict")


def check_request(
    policy: AccessPolicy,
    path: str,
    headers: Mapping[str, str],
    local_address: tuple[str, int],
) -> Verdict:
    """Apply the four rules (module docstring) to one request.

    `headers` is looked up with the canonical capitalisation (`Host`, `Origin`, ...; the
    `websockets` headers are case-insensitive anyway); `local_address` is (address, port) of the
    socket the request arrived on.
    """
    local_ip, port = str(local_address[0]), int(local_address[1])
    host = headers.get("Host")
    if host is None:
        return Verdict(HTTPStatus.BAD_REQUEST, "no Host header")
    if not _host_is_ours(policy, host, local_ip, port):
        return Verdict(HTTPStatus.FORBIDDEN, f"unknown host {host!r}")
    origin = headers.get("Origin")
    if origin is not None and origin.lower() != f"http://{host.lower()}":
        return Verdict(HTTPStatus.FORBIDDEN, f"requests from {origin!r} are not allowed")
    fetch_site = headers.get("Sec-Fetch-Site")
    navigation = (headers.get("Sec-Fetch-Mode") == "navigate"
                  and headers.get("Sec-Fetch-Dest") == "document")
    if fetch_site is not None and fetch_site.lower() not in OWN_FETCH_SITES and not navigation:
        return Verdict(HTTPStatus.FORBIDDEN, f"{fetch_site} requests are not allowed")
    query = parse_qs(path.partition("?")[2])
    if any(_same(value, policy.token) for value in query.get("token", [])):
        return Verdict(set_cookie=True)
    if _same(_cookie(headers.get("Cookie"), cookie_name(port)), policy.token):
        return Verdict()
    scheme, _, credential = (headers.get("Authorization") or "").partition(" ")
    if scheme.lower() == "token" and _same(credential.strip(), policy.token):
        return Verdict()
    return Verdict(HTTPStatus.FORBIDDEN,
                   "missing or wrong token: open the address the IDE printed (?token=...)")


def _same(given: str | None, token: str) -> bool:
    """Token comparison in constant time, so that timing does not reveal a matching prefix."""
    return given is not None and hmac.compare_digest(given.encode(), token.encode())


def _cookie(header: str | None, name: str) -> str | None:
    for part in (header or "").split(";"):
        key, _, value = part.strip().partition("=")
        if key == name:
            return value
    return None


def split_host(host: str) -> tuple[str, int | None]:
    """`name[:port]`, `[v6]:port` -> (lower-case name without brackets, port or None); a port
    that is not a number comes back as -1 (which matches no server)."""
    host = host.strip().lower()
    if host.startswith("["):
        name, _, rest = host[1:].partition("]")
        port_text = rest[1:] if rest.startswith(":") else ""
    elif host.count(":") == 1:
        name, _, port_text = host.partition(":")
    else:
        name, port_text = host, ""
    if not port_text:
        return name, None
    return name, int(port_text) if port_text.isdigit() else -1


def _host_is_ours(policy: AccessPolicy, host: str, local_ip: str, port: int) -> bool:
    name, host_port = split_host(host)
    if (host_port if host_port is not None else 80) != port:
        return False
    if name in LOOPBACK_NAMES or name in policy.host_names:
        return True
    if policy.bound_host not in WILDCARD_HOSTS and name == policy.bound_host:
        return True
    try:  # an address literal is ours when the request arrived on exactly that address
        return _plain_address(name) == _plain_address(local_ip)
    except ValueError:
        return False


def _plain_address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address without its IPv6 zone, an IPv4 one seen through a dual-stack socket unwrapped."""
    address = ipaddress.ip_address(text.split("%")[0])
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address.ipv4_mapped
    return address
