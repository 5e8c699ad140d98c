"""The IDE's request check (`bbzide.ui.access`) and the request heads its port refuses to take
(`bbzide.ui.viser_server.head_problem`), one rule at a time, without a server."""

from __future__ import annotations

from http import HTTPStatus

import pytest

from bbzide.ui.access import (
    AccessPolicy,
    TokenError,
    check_request,
    choose_token,
    cookie_name,
    split_host,
)
from bbzide.ui.viser_server import head_problem

TOKEN = "s3cret-launch-token"
PORT = 8123
LOOPBACK = ("127.0.0.1", PORT)
POLICY = AccessPolicy.for_bind(TOKEN, "127.0.0.1")
COOKIE = {"Cookie": f"{cookie_name(PORT)}={TOKEN}"}


def verdict(path: str = "/", local: tuple[str, int] = LOOPBACK, policy: AccessPolicy = POLICY,
            **headers: str) -> HTTPStatus | None:
    headers = {name.replace("_", "-"): value for name, value in headers.items()}
    headers.setdefault("Host", f"127.0.0.1:{PORT}")
    return check_request(policy, path, headers, local).status


def test_the_token_is_accepted_in_the_address_the_cookie_or_the_authorization_header() -> None:
    assert verdict(f"/?token={TOKEN}") is None
    assert check_request(POLICY, f"/?token={TOKEN}", {"Host": f"127.0.0.1:{PORT}"},
                         LOOPBACK).set_cookie
    assert verdict(**COOKIE) is None
    assert verdict(Authorization=f"token {TOKEN}") is None


def test_no_token_or_a_wrong_one_is_refused() -> None:
    assert verdict() == HTTPStatus.FORBIDDEN
    assert verdict("/?token=guess") == HTTPStatus.FORBIDDEN
    assert verdict(f"/?token={TOKEN}x") == HTTPStatus.FORBIDDEN
    assert verdict(Cookie=f"{cookie_name(PORT)}=guess") == HTTPStatus.FORBIDDEN
    assert verdict(Cookie=f"{cookie_name(PORT + 1)}={TOKEN}") == HTTPStatus.FORBIDDEN  # other IDE
    assert verdict(Authorization=f"Bearer {TOKEN}x") == HTTPStatus.FORBIDDEN


def test_the_cookie_is_http_only_strict_and_named_after_the_port() -> None:
    header = POLICY.cookie_header(PORT)
    assert header.startswith(f"bbzide-token-{PORT}={TOKEN};")
    assert "HttpOnly" in header and "SameSite=Strict" in header and "Path=/" in header


def test_another_origin_is_refused_even_with_the_token() -> None:
    for origin in ("http://127.0.0.5:9000", f"http://127.0.0.1:{PORT + 1}",
                   f"http://localhost:{PORT}", "null", f"https://127.0.0.1:{PORT}"):
        assert verdict(Origin=origin, **COOKIE) == HTTPStatus.FORBIDDEN, origin
    assert verdict(Origin=f"http://127.0.0.1:{PORT}", **COOKIE) is None


def test_a_same_site_or_cross_site_fetch_is_refused_even_with_the_cookie() -> None:
    """`<script src>` from another port of 127.0.0.1 sends no Origin but the cookie."""
    assert verdict(Sec_Fetch_Site="same-site", **COOKIE) == HTTPStatus.FORBIDDEN
    assert verdict(Sec_Fetch_Site="cross-site", **COOKIE) == HTTPStatus.FORBIDDEN
    assert verdict(Sec_Fetch_Site="same-origin", **COOKIE) is None
    assert verdict(Sec_Fetch_Site="none", **COOKIE) is None
    framed = {"Sec_Fetch_Mode": "navigate", "Sec_Fetch_Dest": "iframe"}
    assert verdict(Sec_Fetch_Site="same-site", **framed, **COOKIE) == HTTPStatus.FORBIDDEN


def test_a_link_followed_to_the_ide_is_a_navigation_and_passes_with_the_token() -> None:
    link = {"Sec_Fetch_Mode": "navigate", "Sec_Fetch_Dest": "document"}
    assert verdict(f"/?token={TOKEN}", Sec_Fetch_Site="cross-site", **link) is None
    assert verdict("/", Sec_Fetch_Site="cross-site", **link) == HTTPStatus.FORBIDDEN  # no token


def test_a_rebound_domain_name_or_a_wrong_port_in_host_is_refused() -> None:
    for host in (f"evil.example:{PORT}", f"127.0.0.1.evil.example:{PORT}", "127.0.0.1:80",
                 "127.0.0.1", f"127.0.0.1:{PORT}x", f"192.0.2.7:{PORT}"):
        assert verdict(Host=host, **COOKIE) == HTTPStatus.FORBIDDEN, host
    assert check_request(POLICY, "/", {}, LOOPBACK).status == HTTPStatus.BAD_REQUEST


def test_loopback_names_are_accepted_as_host() -> None:
    for host in (f"localhost:{PORT}", f"127.0.0.1:{PORT}", f"[::1]:{PORT}", f"LOCALHOST:{PORT}"):
        assert verdict(Host=host, **COOKIE) is None, host


def test_a_wildcard_bind_accepts_the_address_the_request_arrived_on_and_no_other() -> None:
    policy = AccessPolicy.for_bind(TOKEN, "0.0.0.0")
    lan = ("192.0.2.2", PORT)
    assert verdict(Host=f"192.0.2.2:{PORT}", local=lan, policy=policy, **COOKIE) is None
    assert verdict(Host=f"192.0.2.3:{PORT}", local=lan, policy=policy, **COOKIE) is not None
    assert verdict(Host=f"evil.example:{PORT}", local=lan, policy=policy, **COOKIE) is not None
    mapped = ("::ffff:192.0.2.2", PORT)  # a dual-stack socket's view of the same address
    assert verdict(Host=f"192.0.2.2:{PORT}", local=mapped, policy=policy, **COOKIE) is None


def test_a_specific_bind_accepts_its_own_address() -> None:
    policy = AccessPolicy.for_bind(TOKEN, "192.0.2.2")
    lan = ("192.0.2.2", PORT)
    assert verdict(Host=f"192.0.2.2:{PORT}", local=lan, policy=policy, **COOKIE) is None
    assert verdict(Host=f"192.0.2.9:{PORT}", local=lan, policy=policy, **COOKIE) is not None


def test_split_host() -> None:
    assert split_host("Example:80") == ("example", 80)
    assert split_host("[::1]:8080") == ("::1", 8080)
    assert split_host("[::1]") == ("::1", None)
    assert split_host("host:x") == ("host", -1)


def test_the_launch_token_comes_from_the_option_the_environment_or_chance() -> None:
    assert choose_token("given-token", {"BBZIDE_TOKEN": "env-token-1"}) == "given-token"
    assert choose_token(None, {"BBZIDE_TOKEN": "env-token-1"}) == "env-token-1"
    fresh = {choose_token(None, {}) for _ in range(3)}
    assert len(fresh) == 3 and all(len(token) >= 40 for token in fresh)
    for bad in ("", "short", "has space in it", "semi;colon-token"):
        with pytest.raises(TokenError):
            choose_token(bad, {})
    with pytest.raises(TokenError, match=r"\$BBZIDE_TOKEN"):
        choose_token(None, {"BBZIDE_TOKEN": "x"})


@pytest.mark.parametrize(
    ("head", "status"),
    [
        (b"POST /editor/socket HTTP/1.1\nContent-Length: 4", HTTPStatus.METHOD_NOT_ALLOWED),
        (b"PUT / HTTP/1.1", HTTPStatus.METHOD_NOT_ALLOWED),
        (b"OPTIONS / HTTP/1.1\nOrigin: http://evil", HTTPStatus.METHOD_NOT_ALLOWED),
        (b"GET / HTTP/1.0", HTTPStatus.HTTP_VERSION_NOT_SUPPORTED),
        (b"GET / HTTP/1.1\nContent-Length: abc", HTTPStatus.BAD_REQUEST),
        (b"GET / HTTP/1.1\nContent-Length: -1", HTTPStatus.BAD_REQUEST),
        (b"GET / HTTP/1.1\nContent-Length: 99999999999", HTTPStatus.BAD_REQUEST),
        (b"GET / HTTP/1.1\nTransfer-Encoding: chunked", HTTPStatus.BAD_REQUEST),
        (b"GET / HTTP/1.1\nno colon here", HTTPStatus.BAD_REQUEST),
        (b"garbage", HTTPStatus.BAD_REQUEST),
    ],
)
def test_request_heads_the_port_cannot_take(head: bytes, status: HTTPStatus) -> None:
    problem = head_problem(head)
    assert problem is not None and problem[0] == status


def test_a_plain_get_passes_the_head_check() -> None:
    assert head_problem(b"GET /?token=x HTTP/1.1\nHost: 127.0.0.1:1\nContent-Length: 0") is None
