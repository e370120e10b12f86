"""Shared memory between the RT driver and other processes: segments and the state segment."""
