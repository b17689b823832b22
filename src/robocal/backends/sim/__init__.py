"""Simulated robots that speak the real wire protocols (CAN frames, servo packets, TCP)."""
