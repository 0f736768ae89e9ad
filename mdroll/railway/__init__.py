"""Railway-acoustics analyses of the roughness models (the analyses layer, above the ensemble):
the physics checks by ensembles (:mod:`.studies`), the 1/3-octave band outputs of a run
(:mod:`.report`) and the work behind ``mdroll roughness`` (:mod:`.tasks`). The models, bands,
tables, measured profiles and the contact filter's formulas are in :mod:`mdroll.roughness`
(bottom layer). See docs/roughness.md."""
