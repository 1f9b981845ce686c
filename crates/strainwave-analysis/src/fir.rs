//! FIR correction of a measured or modelled frequency response (inverse in a pass band).
