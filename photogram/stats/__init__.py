"""Statistics of an adjustment: covariance, reliability, variance components."""
