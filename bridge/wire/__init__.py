"""The bridge's wire: pure codecs from values to bytes and back, nothing that waits.

:mod:`varint` (varints and zigzag), :mod:`compact` (Bottles, with deltas),
:mod:`state_codec` (the robot state, the paper's Table 1), :mod:`frames` (the TCP channel's
frames: hello, auth, data, resume), :mod:`datagrams` (the UDP channel's), :mod:`tiles`
(images and clouds cut into standalone datagrams), :mod:`fec` (Reed-Solomon repairs),
:mod:`transit` (clock stamps on frames), :mod:`link` (the keyed handshake and the tags that
seal every frame and datagram, a sans-IO state machine).  Fed byte by byte and fuzzed in
``tests/bridge``.
"""
