"""Damiao CAN motors (DM4310, DM4340, DM8009, ...: the OpenArm's): the vendor home, protocol layer only.

``tables`` holds the models, registers, command bytes and state codes as data; ``protocol`` packs and unpacks
the frames as pure functions. There is no bus yet (python-can comes with it), so no backend is registered:
see docs/damiao.md for what is built and what is not.
"""

from __future__ import annotations
