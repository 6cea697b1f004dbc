"""What the echoes say about the seabed: the layered coherent forward model
(:mod:`clbeam.seabed.forward`, Rakotonarivo et al.), AVO from the angular
response (:mod:`clbeam.seabed.avo`, Fonseca et al. 2005) and the along-track
sub-bottom profile (:mod:`clbeam.seabed.profile`)."""
