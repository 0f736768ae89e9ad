"""The checks of the thesis's analytic predictions (closed forms in :mod:`mdroll.physics`) against ensembles, and reference solutions in array code (:mod:`.references`)."""
