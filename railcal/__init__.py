"""railcal's application layer: the ``railcal`` command, the demo and the cross-check
workflow. It is the only code that imports :mod:`calibration`, :mod:`fmu_src` and
:mod:`reference_models` together; the layers below never import it."""
