"""Host side of the contact-force algorithms (physics.md section 4), one module per job.

From the bottom up: :mod:`~mdroll.forces.algorithm` (what an algorithm is and what it may
need), :mod:`~mdroll.forces.indenter` (the indenter on the spring grid: curvature, reach, lift
table), :mod:`~mdroll.forces.steps` (where the wheel rolls), :mod:`~mdroll.forces.prepared`
(the lines prepared for the kernels), one launcher module per algorithm
(:mod:`~mdroll.forces.direct`, :mod:`~mdroll.forces.edge`, :mod:`~mdroll.forces.tree`,
:mod:`~mdroll.forces.sweep`), the registry on top of them (:mod:`~mdroll.forces.registry`),
the preparation an algorithm's entry asks for (:mod:`~mdroll.forces.prepare`) and the public
:func:`~mdroll.forces.force.contact_force` (:mod:`~mdroll.forces.force`). The kernels
themselves are in :mod:`mdroll.kernels`.
"""
