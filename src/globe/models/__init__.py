"""Sequential models: counting n-grams over activities and over objects within activity runs."""
