"""The bridge's error family.

* :class:`BridgeUsageError` -- local misuse: a bad configuration, a bad
  command-line argument, a message too big for its channel.  Fix the caller.
* :class:`BridgeProtocolError` -- the peer (or the link) delivered bytes that
  break the bridge protocol: a corrupt, truncated, replayed or unknown frame, a
  datagram from a stranger.  The offending frame is dropped and counted; the
  bridge keeps running.

Any other exception escaping the bridge is a bug.
"""

from __future__ import annotations


class BridgeError(Exception):
    """Base class of every error the bridge raises deliberately."""


class BridgeUsageError(BridgeError):
    """The bridge was configured or called in a way it does not support."""


class BridgeProtocolError(BridgeError):
    """The peer broke the bridge protocol; the message says what and where."""


class NeedMoreData(BridgeProtocolError):
    """The buffer is a correct prefix: wait for more bytes (incremental decoders)."""
