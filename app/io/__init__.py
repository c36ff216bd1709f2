"""Reading and writing recordings: HDF5, CSV, TDMS and the checks every input file passes."""
