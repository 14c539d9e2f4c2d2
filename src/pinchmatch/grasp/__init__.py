"""Stage 2, the grasp: where a thumb-index pinch can hold an object. The hand model decides what a
hand reaches; contact patches give each fingertip's normal and principal curvatures; the rules
decide feasibility; the features describe each pinch as the method's seven haptic features."""
