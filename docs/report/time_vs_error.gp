# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
9.224 97.135 1 "spheres"
16.415 97.135 2 "spheres"
9.504 97.131 1 "+AABB"
16.755 97.131 2 "+AABB"
29.664 97.133 1 ">=1px"
29.724 97.133 2 ">=1px"
29.434 96.976 1 ">=2px"
29.244 96.976 2 ">=2px"
29.534 96.647 1 ">=4px"
29.044 96.647 2 ">=4px"
92.899 66.929 1 "occ 128x64"
81.251 66.929 2 "occ 128x64"
94.981 41.305 1 "occ 256x114"
79.138 41.305 2 "occ 256x114"
104.395 23.400 1 "occ 512x256"
91.305 23.400 2 "occ 512x256"
153.828 15.402 1 "occ 1280x720"
138.666 15.402 2 "occ 1280x720"
5.138 41.305 1 "occ 256x114 kept"
7.221 41.305 2 "occ 256x114 kept"
5.108 15.402 1 "occ 1280x720 kept"
6.660 15.402 2 "occ 1280x720 kept"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
9.9520 102.188 "spheres" 9.224 97.135 1
10.2541 98.815 "+AABB" 9.504 97.131 0
32.0053 102.186 ">=1px" 29.664 97.133 1
31.7572 98.660 ">=2px" 29.434 96.976 0
31.8651 94.963 ">=4px" 29.534 96.647 0
100.2314 68.613 "occ 128x64" 92.899 66.929 0
102.4777 42.989 "occ 256x114" 94.981 41.305 0
112.6347 25.084 "occ 512x256" 104.395 23.400 0
165.9699 17.086 "occ 1280x720" 153.828 15.402 0
5.5435 46.358 "occ 256x114 kept" 5.138 41.305 1
5.5112 20.455 "occ 1280x720 kept" 5.108 15.402 1
EOD
$city_front << EOD
5.108 15.402
5467.66 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
6.083 87.389 1 "spheres"
10.927 87.389 2 "spheres"
6.256 87.350 1 "+AABB"
11.150 87.350 2 "+AABB"
20.546 87.109 1 ">=1px"
19.990 87.109 2 ">=1px"
20.541 86.764 1 ">=2px"
19.923 86.764 2 ">=2px"
20.517 86.311 1 ">=4px"
19.866 86.311 2 ">=4px"
101.534 32.496 1 "occ 128x64"
80.623 32.496 2 "occ 128x64"
95.205 20.092 1 "occ 256x114"
76.168 20.092 2 "occ 256x114"
100.115 11.999 1 "occ 512x256"
83.257 11.999 2 "occ 512x256"
156.219 7.361 1 "occ 1280x720"
132.230 7.361 2 "occ 1280x720"
4.934 20.092 1 "occ 256x114 kept"
8.099 20.092 2 "occ 256x114 kept"
5.114 7.361 1 "occ 1280x720 kept"
7.351 7.361 2 "occ 1280x720 kept"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
6.5628 92.442 "spheres" 6.083 87.389 1
6.7494 89.034 "+AABB" 6.256 87.350 0
22.1675 82.056 ">=1px" 20.546 87.109 1
22.1619 91.817 ">=2px" 20.541 86.764 1
22.1364 87.995 ">=4px" 20.517 86.311 0
109.5479 34.180 "occ 128x64" 101.534 32.496 0
102.7197 21.777 "occ 256x114" 95.205 20.092 0
108.0173 13.684 "occ 512x256" 100.115 11.999 0
168.5491 9.046 "occ 1280x720" 156.219 7.361 0
5.3234 25.145 "occ 256x114 kept" 4.934 20.092 1
5.5180 12.415 "occ 1280x720 kept" 5.114 7.361 1
EOD
$rnd_front << EOD
4.934 20.092
5.114 7.361
5467.66 7.361
EOD
set encoding utf8
set logscale x
set xrange [3.4538:546.766]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, AMD EPYC; 2026-11-28}"
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
