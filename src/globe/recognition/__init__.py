"""Activity recognition from the sensors a home already has (motion, doors, contacts, mats).

features (what each step shows) -> emission (naive Bayes, per home) -> recogniser (GLOBE's
activity filter over the household's activity model, with sensor evidence) -> asking (which
steps to ask the person about) -> metrics (time-slice and class accuracy).
"""
