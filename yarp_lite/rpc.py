"""RpcClient and RpcServer: request/reply over one connection.

An :class:`RpcServer` answers each request: with a ``handler`` the answer is
computed in the receiving thread (no thread hop, the fastest path), without
one the owner calls :meth:`RpcServer.read` then :meth:`RpcServer.reply`.  An
:class:`RpcClient` has at most one output and :meth:`RpcClient.call` sends a
Bottle and waits for the reply, as YARP's ``write(cmd, reply)``.
"""

from __future__ import annotations

from typing import Callable, Optional, Sequence, Union

from yarp_lite.bottle import Bottle
from yarp_lite.errors import NetworkError
from yarp_lite.port import Port

Handler = Callable[[Bottle], Union[Bottle, Sequence, None]]


class RpcServer(Port):
    def __init__(self, name: Optional[str] = None, handler: Optional[Handler] = None,
                 **kwargs) -> None:
        super().__init__(name, reader=handler, rpc=True, **kwargs)

    def read(self, timeout: Optional[float] = None,  # type: ignore[override]
             will_reply: bool = True) -> Optional[Bottle]:
        """The next request; answer it with :meth:`reply`."""
        return super().read(timeout=timeout, will_reply=will_reply)


class RpcClient(Port):
    def __init__(self, name: Optional[str] = None, target: Optional[str] = None,
                 **kwargs) -> None:
        kwargs.setdefault("register", name is not None)
        super().__init__(rpc=True, **kwargs)
        self.open(name or "/rpc_client")
        if target:
            self.connect(target)

    def connect(self, target: str, carrier: str = "") -> bool:
        return self.add_output(target, carrier)

    def call(self, request: Union[Bottle, Sequence], timeout: Optional[float] = None) -> Bottle:
        """Send ``request`` and return the reply; NetworkError if nobody answers."""
        reply = self.write_with_reply(request, timeout=timeout)
        if reply is None:
            raise NetworkError(f"{self.name} is not connected to a server")
        return reply
