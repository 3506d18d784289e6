"""Validation of a calibrated model against the campaign it was fitted to: simulated runs in
service (:mod:`.in_service`), model FRFs of an excitation test (:mod:`.excitation`)."""
