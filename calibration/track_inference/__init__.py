"""Track profile inference: the longitudinal level under the leading bogie from the
calibrated car's measured response (issue 33)."""
