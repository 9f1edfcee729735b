"""The bridge's transport: what carries the wire's bytes, knowing nothing of the GYM.

:mod:`journal` (the durable queues of reliable messages), :mod:`frame_session` (acks,
resume, events and nudges of one TCP connection, sans-IO) and :mod:`channel_phase`,
:mod:`tcp_channel` and :mod:`udp_channel` (the sockets and their threads),
:mod:`adaptive_fec` (repairs sized from the loss the receiver reports), :mod:`copies`
(datagram copies of reliable messages, first copy wins), :mod:`drops` (what is dropped, why,
said once per burst), :mod:`nursery` (every thread started and joined in one place).  A
message's validity reaches it only as a hook (``age``) from the node.
"""
