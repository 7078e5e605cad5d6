# sepbrdf benchmark plot (gnuplot 5).  Embedded into the bench engine by
# CMake; also runs on its own:
#   gnuplot -e "csv='bench/results.csv'; out='bench/results.png'" bench/plot.gp
# Left: factor-step time against N at one J.  Right: time against the
# excess of the error over the Eckart-Young optimum, every run.
if (!exists("csv")) csv = 'bench/results.csv'
if (!exists("out")) out = 'bench/results.png'
if (!exists("J")) J = 8
methods = system("awk -F, 'NR > 1 && !seen[$4]++ { printf \"%s \", $4 }' '" . csv . "'")
set datafile separator ','
set terminal pngcairo size 1400,600 font 'sans,10'
set output out
set multiplot layout 1,2 title 'sepbrdf: factor step, 3 channels (time vs N, time vs excess error)' font 'sans,12'
set logscale xy
set format y '10^{%L}'
set grid
set key top left
set xlabel 'N = R^2 (matrix is N x N per channel)'
set ylabel 'factor step wall time (s)'
set title sprintf('J = %d', J)
rows(m) = sprintf("< awk -F, -v m='%s' -v J=%d '$4 == m && $3 == J' '%s'", m, J, csv)
plot for [m in methods] rows(m) using 1:11 with linespoints title m
# without the baseline (--no-baseline: excess is nan) the relative error itself
if (!exists("nobase")) nobase = 0
ycol = nobase ? 15 : 17
set xlabel 'factor step wall time (s)'
set ylabel (nobase ? 'relative error (no baseline run)' : '(error - optimum) / optimum   (floored at 1e-16)')
set title 'all N and J'
set key bottom left
plot for [m in methods] csv skip 1 using (strcol(4) eq m ? $11 : NaN):(column(ycol) > 1e-16 ? column(ycol) : 1e-16) with points pt 7 ps 0.8 title m
unset multiplot
