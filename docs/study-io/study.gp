# sepbrdf study: headline error vs J. Re-run with `gnuplot study.gp` in this
# folder; `gnuplot -e "outfile='x.png'" study.gp` writes elsewhere.
# Errors below 1e-16 (exact fits) are drawn at 1e-16.
if (!exists("outfile")) outfile = 'study.png'
if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {
    set terminal pngcairo size 1000,640 noenhanced font ',10'
} else {
    set terminal png size 1000,640 noenhanced
}
set output outfile
set title 'sepbrdf study: R = 32, form f'
set xlabel 'J (terms)'
set ylabel 'headline error (relative L2 of f cos theta_i, out of sample)'
set logscale y
set format y '%.0e'
set grid
set key below height 1.5 spacing 1.2
set xtics 1
set xrange [0.5:8.5]
plot 'study.dat' index 0 using 1:2 with linespoints lw 2 title 'lambert:albedo=0.8 (io)', \
     'study.dat' index 1 using 1:2 with linespoints lw 2 title 'microfacet:base=gold,roughness=0.5 (io)', \
     'study.dat' index 2 using 1:2 with linespoints lw 2 title 'microfacet:base=0.2/0.4/0.8,roughness=0.3 (io)'
