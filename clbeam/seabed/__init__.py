"""What the echoes say about the seabed: the layered coherent forward model
(:mod:`clbeam.seabed.forward`, Rakotonarivo et al.), AVO from the angular
response (:mod:`clbeam.seabed.avo`, Fonseca et al. 2005), the along-track
sub-bottom profile (:mod:`clbeam.seabed.profile`) and the normal-incidence
reflection coefficient from the nadir echo and its surface multiple
(:mod:`clbeam.seabed.nadir`)."""
