"""Measuring dances: the metrics (`metrics`), AIST++'s dance features (`dance_features`), the motion style
classifier that gives the paper's FID its features (`motion_style`), real against generated dances on the
test split (`test_split`), the real dances' timing by data folder (`alignment`) and `dancenet evaluate`'s
comparison of every model (`comparison`)."""
