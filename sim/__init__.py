"""frenet-eot simulation testbed: scenarios, traffic, sensors, evaluation, CLI.

``sim`` imports ``tracker``; ``tracker`` never imports ``sim``.
"""
