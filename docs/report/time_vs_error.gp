# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
13.140 97.135 1 "spheres"
28.942 97.135 2 "spheres"
15.379 97.131 1 "+AABB"
31.997 97.131 2 "+AABB"
30.579 97.133 1 ">=1px"
44.240 97.133 2 ">=1px"
30.766 96.976 1 ">=2px"
44.348 96.976 2 ">=2px"
30.828 96.647 1 ">=4px"
42.005 96.647 2 ">=4px"
166.060 66.929 1 "occ 128x64"
150.136 66.929 2 "occ 128x64"
186.297 41.305 1 "occ 256x114"
172.492 41.305 2 "occ 256x114"
222.743 23.400 1 "occ 512x256"
230.091 23.400 2 "occ 512x256"
348.135 15.402 1 "occ 1280x720"
384.173 15.402 2 "occ 1280x720"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
14.2497 102.188 "spheres" 13.140 97.135 1
16.6772 98.815 "+AABB" 15.379 97.131 0
33.1603 102.186 ">=1px" 30.579 97.133 1
33.3631 91.923 ">=2px" 30.766 96.976 1
33.4308 88.225 ">=4px" 30.828 96.647 1
180.0783 68.613 "occ 128x64" 166.060 66.929 0
202.0225 42.989 "occ 256x114" 186.297 41.305 0
241.5450 28.453 "occ 512x256" 222.743 23.400 1
377.5218 20.455 "occ 1280x720" 348.135 15.402 1
EOD
$city_front << EOD
13.140 97.135
15.379 97.131
30.766 96.976
30.828 96.647
150.136 66.929
172.492 41.305
222.743 23.400
348.135 15.402
13446 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
8.653 87.389 1 "spheres"
18.676 87.389 2 "spheres"
8.900 87.350 1 "+AABB"
19.195 87.350 2 "+AABB"
23.378 87.109 1 ">=1px"
31.950 87.109 2 ">=1px"
22.822 86.764 1 ">=2px"
31.605 86.764 2 ">=2px"
22.518 86.311 1 ">=4px"
31.922 86.311 2 ">=4px"
191.385 32.496 1 "occ 128x64"
162.475 32.496 2 "occ 128x64"
210.167 20.092 1 "occ 256x114"
162.464 20.092 2 "occ 256x114"
228.959 11.999 1 "occ 512x256"
202.496 11.999 2 "occ 512x256"
367.049 7.361 1 "occ 1280x720"
332.006 7.361 2 "occ 1280x720"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
9.3834 92.442 "spheres" 8.653 87.389 1
9.6515 89.034 "+AABB" 8.900 87.350 0
25.3514 95.531 ">=1px" 23.378 87.109 1
24.7487 81.711 ">=2px" 22.822 86.764 1
24.4188 91.364 ">=4px" 22.518 86.311 1
207.5409 34.180 "occ 128x64" 191.385 32.496 0
227.9083 21.777 "occ 256x114" 210.167 20.092 0
248.2866 13.684 "occ 512x256" 228.959 11.999 0
398.0329 9.046 "occ 1280x720" 367.049 7.361 0
EOD
$rnd_front << EOD
8.653 87.389
8.900 87.350
22.518 86.311
162.464 20.092
202.496 11.999
332.006 7.361
13446 7.361
EOD
set encoding utf8
set logscale x
set xrange [6.0571:1344.6]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, Intel(R) Xeon(R) Processor; 2026-11-26}"
  set title 'city scene walk'
  plot $city_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $city_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $city using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $city using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $city_labels using 1:2:3 with labels left font ',10' notitle
  set title 'random towns (3)'
  plot $rnd_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $rnd_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $rnd using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $rnd using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $rnd_labels using 1:2:3 with labels left font ',10' notitle
  unset multiplot
  set output
}
