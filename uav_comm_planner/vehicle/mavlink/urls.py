"""Vehicle link URLs, checked before anything is opened.

pymavlink opens almost any string: a log file to replay, a Unix socket, a websocket, a CSV
file. The planner accepts only the links to a live vehicle, in pymavlink's spelling:

- ``tcp:HOST:PORT`` (connect), ``tcpin:HOST:PORT`` (listen), ``udp:HOST:PORT`` /
  ``udpin:HOST:PORT`` (listen), ``udpout:HOST:PORT``, ``udpbcast:HOST:PORT``: HOST an IPv4
  address or a host name (checked for its spelling, never looked up here: a lookup may block),
  PORT in 1..65535;
- ``/dev/NAME`` or ``/dev/NAME,BAUD``: a serial device that exists and is a character device,
  BAUD in 50..10 000 000 (115200 when not given); serial links need pyserial, the
  ``serial`` extra (``pip install 'uav_comm_planner[serial]'``).

:func:`parse_link_url` returns a :class:`LinkUrl` or raises
:class:`~uav_comm_planner.errors.InvalidLinkUrlError` saying what is wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
import importlib.util
import ipaddress
import os
import re
import stat

from uav_comm_planner.errors import InvalidLinkUrlError

#: Network schemes pymavlink opens, and what each does.
NETWORK_SCHEMES = {
    'tcp': 'connect to a TCP server', 'tcpin': 'listen for one TCP client',
    'udp': 'listen on UDP', 'udpin': 'listen on UDP', 'udpout': 'send UDP to',
    'udpbcast': 'broadcast UDP to',
}
BAUD_RANGE = (50, 10_000_000)
DEFAULT_BAUD = 115200
#: Linux's major number of /dev/null, /dev/zero, /dev/random, /dev/mem...: never a serial port.
MEMORY_DEVICES_MAJOR = 1
#: A URL longer than this is refused before it is parsed.
MAX_URL_LENGTH = 512
_HOST_LABEL = re.compile(r'(?!-)[A-Za-z0-9-]{1,63}(?<!-)')
EXAMPLES = 'tcp:127.0.0.1:5760, udpin:0.0.0.0:14550 or /dev/ttyACM0,115200'


@dataclass(frozen=True)
class LinkUrl:
    """A checked link: ``scheme`` (``serial`` for a device), ``host`` and ``port``, or
    ``device`` and ``baud``. ``str()`` is the string pymavlink is given."""

    scheme: str
    host: str = ''
    port: int = 0
    device: str = ''
    baud: int = DEFAULT_BAUD

    @property
    def serial(self) -> bool:
        return self.scheme == 'serial'

    def __str__(self) -> str:
        if self.serial:
            return f'{self.device},{self.baud}'
        return f'{self.scheme}:{self.host}:{self.port}'


def serial_available() -> bool:
    """Whether pyserial (``import serial``), which pymavlink opens serial devices with, is
    installed."""
    return importlib.util.find_spec('serial') is not None


def parse_link_url(text: object) -> LinkUrl:
    """Check ``text`` as a vehicle link URL (module docstring); raise InvalidLinkUrlError."""
    if not isinstance(text, str):
        raise InvalidLinkUrlError(f'a link URL is a string, got {type(text).__name__}')
    if len(text) > MAX_URL_LENGTH:
        raise InvalidLinkUrlError(f'the link URL is longer than {MAX_URL_LENGTH} characters')
    if not text or not text.isprintable() or text != text.strip() or ' ' in text:
        raise InvalidLinkUrlError(f'link URL {text!r} is empty or holds spaces or control '
                                  f'characters; give one like {EXAMPLES}')
    if text.startswith('/'):
        return _serial(text)
    scheme, _, rest = text.partition(':')
    if scheme not in NETWORK_SCHEMES:
        raise InvalidLinkUrlError(
            f'link URL {text!r}: unknown kind {scheme!r}; use one of '
            f'{", ".join(f"{s}:HOST:PORT" for s in NETWORK_SCHEMES)} or a serial device '
            f'/dev/NAME[,BAUD]')
    host, colon, port = rest.rpartition(':')
    if not colon or not host:
        raise InvalidLinkUrlError(f'link URL {text!r}: expected {scheme}:HOST:PORT')
    _check_host(text, host)
    return LinkUrl(scheme, host=host, port=_port(text, port))


def _check_host(text: str, host: str) -> None:
    try:
        ipaddress.IPv4Address(host)
        return
    except ValueError:
        pass
    labels = host.rstrip('.').split('.')
    if (len(host) > 253 or labels[-1].isdigit()
            or not all(_HOST_LABEL.fullmatch(label) for label in labels)):
        raise InvalidLinkUrlError(f'link URL {text!r}: {host!r} is neither an IPv4 address nor '
                                  f'a host name')


def _port(text: str, port: str) -> int:
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InvalidLinkUrlError(f'link URL {text!r}: the port must be a number in 1..65535, '
                                  f'got {port!r}')
    return int(port)


def _serial(text: str) -> LinkUrl:
    device, comma, baud_text = text.partition(',')
    if not device.startswith('/dev/') or '/../' in device + '/':
        raise InvalidLinkUrlError(f'link URL {text!r}: a serial link is a device under /dev/, '
                                  f'such as /dev/ttyACM0,115200')
    baud = DEFAULT_BAUD
    if comma:
        if not baud_text.isdigit() or not BAUD_RANGE[0] <= int(baud_text) <= BAUD_RANGE[1]:
            raise InvalidLinkUrlError(f'link URL {text!r}: the baud rate must be a number in '
                                      f'{BAUD_RANGE[0]}..{BAUD_RANGE[1]}, got {baud_text!r}')
        baud = int(baud_text)
    try:
        info = os.stat(device)
    except OSError as exc:
        raise InvalidLinkUrlError(f'link URL {text!r}: cannot use {device}: '
                                  f'{exc.strerror or exc}') from None
    if not stat.S_ISCHR(info.st_mode):
        raise InvalidLinkUrlError(f'link URL {text!r}: {device} is not a character device '
                                  f'(a serial port)')
    if os.major(info.st_rdev) == MEMORY_DEVICES_MAJOR:
        raise InvalidLinkUrlError(f'link URL {text!r}: {device} is a memory device (like '
                                  f'/dev/zero or /dev/null), not a serial port')
    if not serial_available():
        raise InvalidLinkUrlError(f'link URL {text!r}: serial links need pyserial; install the '
                                  f"serial extra: pip install 'uav_comm_planner[serial]'")
    return LinkUrl('serial', device=device, baud=baud)


__all__ = ['BAUD_RANGE', 'LinkUrl', 'NETWORK_SCHEMES', 'parse_link_url', 'serial_available']
