"""What the toolbox writes and reads: figures and their captions, the HTML report, saved models
(``.npz`` plus JSON, never pickle) and field records (``.npz`` / ``.csv``)."""
