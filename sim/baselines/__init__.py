"""External baseline trackers for the study (``eot compare``): trackers nobody in this project wrote,
wrapped to the runner's tracker interface (``step(frame) -> list[tracker.Track]``).

- ``sim.baselines.stonesoup_gmphd``: Stone Soup's GM-PHD filter with its unscented Kalman filter on
  the lidar cluster centroids (optional extra ``baselines``: ``pip install -e ".[baselines]"``).
"""
