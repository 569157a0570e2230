"""Passwords in database URLs: found, masked and refused before they reach any log.

Snakemake prints its whole command line (``--config`` included) in its banner and keeps it in
``.snakemake/log/``, records every rule's params in ``.snakemake/metadata/``, and the result cache
records them too. A password written into ``tune.storage`` would land in all of them, so the
validator refuses it from any source (command line or config file) and says how to give it
instead: libpq, under every PostgreSQL driver, reads ``PGPASSWORD`` and ``~/.pgpass`` when the URL
has none. Every :class:`~graspstab.config.errors.ConfigError` message is passed through
:func:`mask_text`, so no configuration message echoes a password either.
"""

from __future__ import annotations

import re

MASK = "***"
# The userinfo password of a URL in free text: scheme://user:PASSWORD@ (up to the last @ of the
# token, so a raw @ inside the password is masked too), and a password=... query parameter.
_USERINFO = re.compile(r"(?P<head>\b[A-Za-z][A-Za-z0-9+.\-]*://[^\s:/@'\"]*:)[^\s'\"]*@")
_QUERY = re.compile(r"(?P<head>[?&]password=)[^&\s'\"]*", re.IGNORECASE)

PASSWORD_HELP = (
    "the password where libpq (the PostgreSQL client library under psycopg2, SQLAlchemy and "
    "Optuna) reads it when the URL has none: a line host:port:database:user:password in "
    "~/.pgpass (chmod 600; on a cluster, in the home directory the jobs share), or the "
    "environment variable PGPASSWORD in the shell that starts Snakemake (docs/cluster.md, "
    "'A shared Optuna database')"
)


def _userinfo_password(url: str) -> str | None:
    """The password between ``scheme://user:`` and the URL's last ``@``, or None. SQLite URLs
    (``sqlite:////path``) hold a path, never credentials."""
    if url.lower().startswith("sqlite"):
        return None
    at = url.rfind("@")
    if at < 0:
        return None
    slashes = url.rfind("//", 0, at)
    userinfo = url[slashes + 2 if slashes >= 0 else 0 : at]
    if ":" not in userinfo or "/" in userinfo.split(":", 1)[0]:
        return None
    return userinfo.split(":", 1)[1]


def url_password(url: str) -> str | None:
    """The non-empty password ``url`` carries (in its userinfo or as ``?password=``), else None."""
    found = _userinfo_password(url)
    if not found:
        query = re.search(r"[?&]password=([^&]*)", url, re.IGNORECASE)
        found = query.group(1) if query else None
    return found or None


def mask_text(text: str) -> str:
    """``text`` with every URL password (userinfo or ``password=`` parameter) replaced by
    ``***``."""
    text = _USERINFO.sub(lambda m: f"{m.group('head')}{MASK}@", text)
    return _QUERY.sub(lambda m: f"{m.group('head')}{MASK}", text)


def mask_url(url: str) -> str:
    """``url`` with its password shown as ``***`` (also when the password holds a raw ``@``)."""
    return mask_text(url)


def strip_password(url: str) -> str:
    """``url`` without its password: ``scheme://user@host/db``, no ``password=`` parameter."""
    text = _USERINFO.sub(lambda m: f"{m.group('head')[:-1]}@", url)
    text = re.sub(r"([?&])password=[^&]*&?", r"\1", text, flags=re.IGNORECASE)
    return text.rstrip("?&")


def check_storage(cfg: dict) -> None:
    """Refuse a ``tune.storage`` URL that holds a password, from any source (a config file or the
    command line): masked, with the URL to give instead and where the password goes."""
    from graspstab.config.errors import ConfigError  # errors imports this module

    url = (cfg.get("tune") or {}).get("storage")
    if not isinstance(url, str) or url_password(url) is None:
        return
    other = "" if url.lower().startswith("postgres") else (
        " (another database's driver: its own password file or environment)"
    )
    raise ConfigError(
        f"tune.storage = {mask_url(url)} holds a password, which Snakemake would print in its "
        "banner and keep in .snakemake/log/ (the --config line) and .snakemake/metadata/ (the "
        f"tuning jobs' params). Give the URL without it, {strip_password(url)}, and "
        f"{PASSWORD_HELP}{other}."
    )
