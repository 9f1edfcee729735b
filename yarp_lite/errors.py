"""The yarp_lite error family.

Every failure yarp_lite raises on purpose is a :class:`YarpError`.  It comes in
three kinds, so callers can tell whose fault it is:

* :class:`LocalProtocolError` -- the caller misused the API (an invalid port
  name, writing to a closed port, an unencodable value).  Fix the calling code.
* :class:`RemoteProtocolError` -- a peer sent bytes that break the YARP
  protocol (a bad header, a bogus length, a truncated Bottle).  The connection
  that carried them is dropped; the port keeps serving everyone else.
  :class:`AuthenticationError`, one of them, is what a wrong or missing
  ``auth.conf`` key gives.
* :class:`NetworkError` -- the network or the name server did not answer
  (refused, timed out, not registered).  Usually worth retrying.

Any other exception escaping yarp_lite is a bug.
"""

from __future__ import annotations


class YarpError(Exception):
    """Base class of every error yarp_lite raises deliberately."""


class LocalProtocolError(YarpError):
    """The API was used in a way YARP does not allow."""


class RemoteProtocolError(YarpError):
    """A peer broke the protocol; ``where`` says which stream and which phase."""

    def __init__(self, message: str, where: str = "") -> None:
        super().__init__(f"{where}: {message}" if where else message)
        self.where = where


class AuthenticationError(RemoteProtocolError):
    """A connection failed YARP's port authentication (``auth.conf``, AuthHMAC).

    The peer signed with another key, did not sign at all, or did not answer
    within YARP's 2 s.  The connection is dropped on both sides; the message
    says which ``auth.conf`` this side used (or that it found none).
    Retrying does not help: the keys must match.
    """


class NeedMoreData(RemoteProtocolError):
    """Input ended in the middle of an item.

    Raised by the pure decoders when a buffer is a correct prefix of a message:
    incremental readers catch it and wait for more bytes; whole-buffer decoders
    let it escape as a truncation error.
    """


class NetworkError(YarpError):
    """A peer or the name server could not be reached or did not answer."""
