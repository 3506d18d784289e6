"""How the box model's particles search: the defaults of a shaker campaign's calibration
(:func:`calibration.calibrate_box.calibrate_box_campaign`) and of targets given by mode type
(``railcal calibrate --targets``), kept here without imports so that the command line's
help can state them without loading the model. docs/methods/calibration-box.md (sections 4
and 7) gives the runs that chose each value."""

#: A shaker campaign's particles run as this many independent swarms, because one swarm can
#: stop at the seed's 0.5 % in a basin no refinement leaves (the demo's test did).
CAMPAIGN_SWARMS = 4
#: A campaign's search ends once a refined swarm is within this [%] of every identified mode:
#: about twice the identification's resolution on the synthetic tests (0.03-0.07 %).
CAMPAIGN_DONE_PCT = 0.1

#: A typed target (an idealised floor pattern) counts only when its partner's MAC with the
#: pattern is at least this and no other target shares the partner; without it a typed fit
#: met every frequency with modes unlike their types.
TYPED_MIN_MAC = 0.8
#: Sequential-LP steps on the full model that keep the MAC floor after the CasADi refinement,
#: which fits frequencies only and has its rounds refused where the floor binds.
TYPED_POLISH_STEPS = 30
#: Typed targets: independent swarms, each refined and polished, the best kept; one swarm
#: gathers on a single basin (on seed Figure 5 the stiff-end-wall one, stuck above 0.5 %).
TYPED_SWARMS = 4
#: Rounds of the CasADi refinement for typed targets.
TYPED_REFINE_ROUNDS = 20
