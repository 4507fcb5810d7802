"""The figure notebooks' Jupyter kernel: an IPython extension the ``tiltpile`` kernel loads at its
start (``make setup`` writes ``--IPKernelApp.extra_extensions=tiltpile.figures.kernel`` into its
kernel spec) that drops one line of the kernel's log, ipykernel's ``KeyboardInterrupt caught in
kernel``, and nothing else.

Why the line came after notebooks that ran without fault (one in eight of a ``make figures
PRESET=smoke``): papermill ends every notebook with a ``kernel_info_request`` and waits for its
reply, not for the kernel to go idle, then shuts the kernel down; jupyter_client's shutdown,
graceful or immediate, first interrupts the kernel (SIGINT to its process group). While a
request's handler runs, ipykernel holds Python's default SIGINT handler, so a signal landing
after the reply was sent but before the handler returned raises KeyboardInterrupt there, which
ipykernel catches and logs at ERROR (``ipykernel/kernelbase.py``). No real error is hidden: an
interrupt of a cell's code is the cell's error (papermill fails on it), and every other record
of the kernel's log passes at the level its spec sets (ERROR).
"""

from __future__ import annotations

import logging

#: what ipykernel logs when a SIGINT lands in the kernel outside a cell's code (a request's
#: handler, or its event loop)
SHUTDOWN_INTERRUPT = ("KeyboardInterrupt caught in kernel.", "KeyboardInterrupt caught in kernel")


def not_the_shutdown_interrupt(record: logging.LogRecord) -> bool:
    """A logging filter: False for the records of ``SHUTDOWN_INTERRUPT`` only."""
    return record.getMessage() not in SHUTDOWN_INTERRUPT


def load_ipython_extension(ipython) -> None:
    """Filter the kernel's log (the kernel application's logger, ``IPKernelApp``)."""
    kernel = getattr(ipython, "kernel", None)
    log = kernel.log if kernel is not None else logging.getLogger("IPKernelApp")
    if not_the_shutdown_interrupt not in log.filters:
        log.addFilter(not_the_shutdown_interrupt)
