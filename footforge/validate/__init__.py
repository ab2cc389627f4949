"""`footforge validate`: drop tests of every variant against the closed chain, a fidelity report,
and calibration of the derived feet's passive joints; stance checks of built robots."""
