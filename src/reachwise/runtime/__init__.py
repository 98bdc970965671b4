"""Process settings of a real-time loop: the garbage collector, the GIL's switch
interval, ``SCHED_FIFO`` priority, the C library's memory and transparent huge pages.

They read ``/proc`` and change the state of the operating system, so they sit at the
I/O layer beside :mod:`reachwise.io`, not in the control maths; the collision server,
``reachwise serve`` and the benchmarks apply them (:mod:`reachwise.runtime.realtime`).
"""
