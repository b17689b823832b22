"""Damiao CAN motors (DM4310, DM4340, DM8009, ...: the OpenArm's): the vendor home.

``tables`` holds the models, registers, command bytes and state codes as data; ``protocol`` and ``modes`` pack
and unpack the frames as pure functions; ``faults`` names the error states. ``bus`` is the python-can bus
(backend ``damiao``); ``sim`` / ``sim_bus`` simulate the motors and ``openarm`` a whole OpenArm v10 arm. See
docs/damiao.md for what is modelled and what is assumed.
"""

from __future__ import annotations
