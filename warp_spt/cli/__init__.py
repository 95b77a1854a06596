"""The ``warp-spt`` command line: ``main`` parses and dispatches down to one runner per command.

``options`` (every flag, Options, settings_of), ``budget_flags``, ``common`` (exit statuses, errors,
messages, the pieces runners share), ``view_checks`` (recentring, framing, probes, warnings, studio:
the view of a single image and of every animation frame), and the runners ``render`` (one image),
``progressive`` (budgets and error targets), ``animation`` (frames and clusters) and ``convergence``.
"""
