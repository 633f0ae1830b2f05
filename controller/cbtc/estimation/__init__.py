"""Where each train is: per-train filters, fix consensus, the estimate and its bounds (pure)."""
