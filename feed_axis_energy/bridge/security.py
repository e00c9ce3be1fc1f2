"""Who may talk to the OPC UA server, decided once from the address it is bound to.

On a loopback address (``127.0.0.0/8``, ``::1``, ``localhost``) anonymous clients without
encryption are accepted: only processes on this computer reach it. Anywhere else the server
offers one endpoint, ``Basic256Sha256`` with ``SignAndEncrypt``, and a user name and password
from :attr:`OpcUaSecurity.users`; without a server certificate, its key and at least one user
it refuses to start (:class:`~feed_axis_energy.errors.ConfigError`). Client certificates are
accepted when :attr:`OpcUaSecurity.trusted_clients` is empty, else only those listed
(compared byte for byte, DER).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import hmac
import ipaddress
from pathlib import Path
from typing import Any, Mapping, Sequence

from asyncua import ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.user_managers import UserManager

from ..errors import ConfigError

__all__ = ['is_loopback', 'OpcUaSecurity', 'PasswordUsers', 'read_users_file', 'SecurityPlan',
           'security_plan']

MAX_USERS_FILE_BYTES = 64 * 1024


@dataclass(frozen=True)
class OpcUaSecurity:
    """The OPC UA server's credentials.

    Attributes
    ----------
    certificate, private_key
        The server's application instance certificate (DER or PEM) and its private key (PEM);
        required off loopback.
    users
        User name -> password; required off loopback.
    trusted_clients
        Client certificates (DER or PEM files) accepted on a secure channel; empty: any.
    """

    certificate: Path | None = None
    private_key: Path | None = None
    users: Mapping[str, str] = field(default_factory=dict)
    trusted_clients: Sequence[Path] = ()


@dataclass(frozen=True)
class SecurityPlan:
    """What the server offers: endpoint policies and the identity tokens it accepts."""

    loopback: bool
    policies: tuple[ua.SecurityPolicyType, ...]
    tokens: tuple[type, ...]
    anonymous: bool


def is_loopback(host: str) -> bool:
    """True when ``host`` is ``localhost`` or a loopback address (names are not resolved)."""
    if host.strip().lower() == 'localhost':
        return True
    try:
        return ipaddress.ip_address(host.strip('[]')).is_loopback
    except ValueError:
        return False


def security_plan(host: str, security: OpcUaSecurity) -> SecurityPlan:
    """Decide the endpoints and identity tokens for a server bound to ``host``.

    Parameters
    ----------
    host
        The address the server listens on.
    security
        The credentials at hand.

    Returns
    -------
    SecurityPlan
        Loopback: no security and anonymous (plus the encrypted endpoint and user names when
        a certificate and users are given). Elsewhere: ``Basic256Sha256_SignAndEncrypt``
        and user names only.

    Raises
    ------
    ConfigError
        Off loopback without a certificate, its key or a user; a user without a password.
    """
    for name, password in security.users.items():
        if not name or not isinstance(password, str) or not password:
            raise ConfigError('every user needs a name and a non-empty password',
                              file='<opcua>', key=f'users.{name}')
    has_cert = security.certificate is not None and security.private_key is not None
    secure = ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt
    if is_loopback(host):
        policies: tuple[ua.SecurityPolicyType, ...] = (ua.SecurityPolicyType.NoSecurity,)
        tokens: tuple[type, ...] = (ua.AnonymousIdentityToken,)
        if has_cert:
            policies += (secure,)
        if security.users:
            tokens += (ua.UserNameIdentityToken,)
        return SecurityPlan(loopback=True, policies=policies, tokens=tokens, anonymous=True)
    missing = [what for what, value in (('a server certificate', security.certificate),
                                        ('its private key', security.private_key))
               if value is None]
    if not security.users:
        missing.append('at least one user with a password')
    if missing:
        msg = (f'the OPC UA server bound to {host!r} (not loopback) requires Basic256Sha256 '
               f'with certificates and user names; missing: {", ".join(missing)}')
        raise ConfigError(msg, file='<opcua>', key='host')
    return SecurityPlan(loopback=False, policies=(secure,),
                        tokens=(ua.UserNameIdentityToken,), anonymous=False)


class PasswordUsers(UserManager):
    """asyncua's user manager: anonymous where the plan allows it, else name and password.

    Parameters
    ----------
    users
        User name -> password.
    anonymous
        Whether a session without a user name is accepted.
    """

    def __init__(self, users: Mapping[str, str], *, anonymous: bool):
        self._users = {name.encode(): password.encode() for name, password in users.items()}
        self._anonymous = anonymous

    def get_user(self, iserver: Any, username: str | None = None,
                 password: str | None = None, certificate: Any = None) -> User | None:
        """Return the session's user, or None to refuse it (asyncua's interface)."""
        if username is None:
            # the role that may read and call; asyncua's Anonymous role may do nothing
            return User(role=UserRole.User) if self._anonymous else None
        given = (password or '').encode()
        want = self._users.get(username.encode())
        if want is None:
            hmac.compare_digest(given, given)   # same work whether the name exists or not
            return None
        if not hmac.compare_digest(given, want):
            return None
        return User(role=UserRole.User, name=username)


def read_users_file(path: Path) -> dict[str, str]:
    """The OPC UA users of a text file: one ``name:password`` a line.

    Blank lines and lines starting with ``#`` are skipped; the password is everything after
    the first ``:`` (it may hold colons). The file is not echoed in messages (passwords).

    Raises
    ------
    ConfigError
        The file cannot be read, is larger than 64 KiB or not UTF-8, a line has no ``:``, an
        empty name or password, or a name given twice (``file:line``).
    """
    try:
        with open(path, 'rb') as stream:
            raw = stream.read(MAX_USERS_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f'cannot read the users file: {exc.strerror}', file=str(path)) from None
    if len(raw) > MAX_USERS_FILE_BYTES:
        raise ConfigError(f'a users file is at most {MAX_USERS_FILE_BYTES} bytes',
                          file=str(path))
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError:
        raise ConfigError('a users file is UTF-8 text', file=str(path)) from None
    users: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith('#'):
            continue
        name, colon, password = line.partition(':')
        name = name.strip()
        where = f'{path}:{number}'
        if not colon or not name or not password:
            raise ConfigError('expected name:password with both non-empty', file=where)
        if name in users:
            raise ConfigError(f'user {name!r} is given twice', file=where)
        users[name] = password
    return users
