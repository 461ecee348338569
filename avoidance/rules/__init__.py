"""Rules of the air on the UAS side (spec §7.6-7.7): the rule engine, the rules and the
trajectory restrictions they put on the navigation reach set."""
