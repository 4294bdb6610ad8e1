0 0 0 ; start
100 0.001 -0.001 # end

# notes
