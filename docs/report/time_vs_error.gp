# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
16.361 97.135 1 "spheres"
21.620 97.135 2 "spheres"
26.509 97.131 1 "+AABB"
26.129 97.131 2 "+AABB"
57.327 97.133 1 ">=1px"
45.485 97.133 2 ">=1px"
56.034 96.976 1 ">=2px"
44.092 96.976 2 ">=2px"
55.143 96.647 1 ">=4px"
42.950 96.647 2 ">=4px"
213.263 66.929 1 "occ 128x64"
178.513 66.929 2 "occ 128x64"
219.865 41.305 1 "occ 256x114"
185.586 41.305 2 "occ 256x114"
288.598 23.400 1 "occ 512x256"
207.522 23.400 2 "occ 512x256"
381.407 15.402 1 "occ 1280x720"
337.560 15.402 2 "occ 1280x720"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
17.7116 102.188 "spheres" 16.361 97.135 1
28.6973 92.078 "+AABB" 26.509 97.131 1
62.0593 92.080 ">=1px" 57.327 97.133 1
60.6596 95.291 ">=2px" 56.034 96.976 0
59.6950 101.700 ">=4px" 55.143 96.647 1
230.8678 68.613 "occ 128x64" 213.263 66.929 0
238.0153 42.989 "occ 256x114" 219.865 41.305 0
312.4217 25.084 "occ 512x256" 288.598 23.400 0
412.8920 17.086 "occ 1280x720" 381.407 15.402 0
EOD
$city_front << EOD
16.361 97.135
26.129 97.131
42.950 96.647
178.513 66.929
185.586 41.305
207.522 23.400
337.560 15.402
16347.6 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
13.769 87.389 1 "spheres"
14.983 87.389 2 "spheres"
11.799 87.350 1 "+AABB"
13.689 87.350 2 "+AABB"
28.593 87.109 1 ">=1px"
27.281 87.109 2 ">=1px"
30.477 86.764 1 ">=2px"
27.530 86.764 2 ">=2px"
30.552 86.311 1 ">=4px"
27.130 86.311 2 ">=4px"
213.191 32.496 1 "occ 128x64"
169.919 32.496 2 "occ 128x64"
243.356 20.092 1 "occ 256x114"
171.160 20.092 2 "occ 256x114"
271.343 11.999 1 "occ 512x256"
191.115 11.999 2 "occ 512x256"
467.073 7.361 1 "occ 1280x720"
312.366 7.361 2 "occ 1280x720"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
14.9060 82.336 "spheres" 13.769 87.389 1
12.7726 92.403 "+AABB" 11.799 87.350 1
30.9537 92.162 ">=1px" 28.593 87.109 1
32.9927 88.449 ">=2px" 30.477 86.764 0
33.0737 84.626 ">=4px" 30.552 86.311 0
230.7904 34.180 "occ 128x64" 213.191 32.496 0
263.4446 21.777 "occ 256x114" 243.356 20.092 0
293.7426 13.684 "occ 512x256" 271.343 11.999 0
505.6301 9.046 "occ 1280x720" 467.073 7.361 0
EOD
$rnd_front << EOD
11.799 87.350
27.130 86.311
169.919 32.496
171.160 20.092
191.115 11.999
312.366 7.361
16347.6 7.361
EOD
set encoding utf8
set logscale x
set xrange [8.25907:1634.76]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, AMD EPYC; 2026-11-21}"
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
