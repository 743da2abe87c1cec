"""The solver's estimators of a view, each from the same eye rays (:mod:`.eye`).

* :mod:`.local_estimate` — the double local estimate from a store's light-chain nodes, per
  pixel (the unbiased reference; :func:`lsadphoto.solver.render`);
* :mod:`.surface_cache` — direct light per pixel, indirect light interpolated from a
  view-independent cache on the surfaces (``render --estimator cache``);
* :mod:`.path_tracer` — path tracing from the eye with next-event estimation, the
  independent cross-check (:func:`lsadphoto.solver.render_path_traced`).

They sit above the store and the light chains and below :mod:`lsadphoto.solver.simulation`
(which renders low-resolution views to meet a target error) and
:mod:`lsadphoto.solver.rendering` (the public entry point).
"""
