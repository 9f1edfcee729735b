"""yarp_lite: a pure-Python YARP 3.5 that real YARP cannot tell apart.

Public surface::

    from yarp_lite import Bottle, Port, BufferedPort, RpcClient, RpcServer, network

Layers, bottom up: :mod:`bottle`/:mod:`bottle_text`/:mod:`framing` (pure
codecs), :mod:`carriers` (tcp, fast_tcp, udp, text, text_ack, name_ser),
:mod:`connection`/:mod:`stream` (sockets), :mod:`port` (ports: their inputs,
delivery, outputs and registration in modules of their own),
:mod:`nameclient`/:mod:`network` (the network), :mod:`nameserver` (the
server) and :mod:`cli` (the ``yarp-lite`` tool).
"""

__version__ = "0.1.0"

from yarp_lite.bottle import (Bottle, Dict, Float32, Float64, Int8, Int16, Int32, Int64,  # noqa: E402
                              Vocab)
from yarp_lite.contact import Contact  # noqa: E402
from yarp_lite.errors import (AuthenticationError, LocalProtocolError, NetworkError,  # noqa: E402
                              RemoteProtocolError, YarpError)

__all__ = ["Bottle", "Dict", "Float32", "Float64", "Int8", "Int16", "Int32", "Int64", "Vocab",
           "Contact", "YarpError", "LocalProtocolError", "RemoteProtocolError", "NetworkError",
           "AuthenticationError", "Port", "BufferedPort", "RpcClient", "RpcServer", "NameClient", "__version__"]


def __getattr__(name: str):
    """Ports and the name client load lazily, so importing the codecs stays cheap."""
    if name == "Port":
        from yarp_lite.port import Port
        return Port
    if name in ("BufferedPort",):
        from yarp_lite.buffered_port import BufferedPort
        return BufferedPort
    if name in ("RpcClient", "RpcServer"):
        from yarp_lite import rpc
        return getattr(rpc, name)
    if name == "NameClient":
        from yarp_lite.nameclient import NameClient
        return NameClient
    raise AttributeError(name)
