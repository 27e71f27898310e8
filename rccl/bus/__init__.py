"""Event flag triples across processes and hosts on the Zenoh bus (docs/zenoh.md).

``rccl.bus.planning`` is the planning process's side (``BusEvents``, ``rccl.events``' API
with arms in other processes), ``rccl.bus.arm`` an arm process (``python -m rccl.bus.arm``),
``rccl.bus.wire`` what crosses between them, ``rccl.bus.remote`` the planning side's view of
a remote arm and its EFTs, ``rccl.bus.heartbeat`` the heartbeat both sides send.
"""
