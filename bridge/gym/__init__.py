"""The bridge's GYM policy: what the link owes a Generic YARP Module and its pilot.

:mod:`delivery` (the inbox written to the modules' ports in order, receipts, cancels),
:mod:`expiry` (a command's validity aged by the time each side held it),
:mod:`status_events` (the status change a pilot waits for leaves at once),
:mod:`stop_line` (the stop-all's order and acknowledgement), :mod:`presence` and
:mod:`stand_ins` (a module's ports shown on the pilot's name server while it runs on the
robot).  It uses the transport; the transport never imports it.
"""
