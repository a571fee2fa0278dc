// The report's 3D view (pliant.cli.view3d): __ID__ is the view's element id.
(function(){
const root=document.getElementById("__ID__"),cv=root.querySelector("canvas"),
 g=cv.getContext("2d"),D=JSON.parse(root.querySelector("script[type='application/json']").textContent),
 slider=root.querySelector("input"),label=root.querySelector("figcaption span");
const all=[];D.meshes.forEach(m=>all.push(m.v));D.lines.concat(D.points).forEach(l=>all.push(l.p));
D.steps.forEach(s=>s.forEach(l=>all.push(l.p)));
let lo=[1e9,1e9,1e9],hi=[-1e9,-1e9,-1e9];
all.forEach(a=>{for(let i=0;i<a.length;i+=3)for(let k=0;k<3;k++){lo[k]=Math.min(lo[k],a[i+k]);hi[k]=Math.max(hi[k],a[i+k]);}});
const c=[0,1,2].map(k=>(lo[k]+hi[k])/2),R=Math.max(1e-6,Math.hypot(hi[0]-lo[0],hi[1]-lo[1],hi[2]-lo[2])/2);
let yaw=-0.9,pitch=0.45,zoom=1,step=D.start;
function basis(){const d=[Math.cos(pitch)*Math.cos(yaw),Math.cos(pitch)*Math.sin(yaw),Math.sin(pitch)],
 r=[-Math.sin(yaw),Math.cos(yaw),0],u=[d[1]*r[2]-d[2]*r[1],d[2]*r[0]-d[0]*r[2],d[0]*r[1]-d[1]*r[0]];return [d,r,u];}
function project(p){const [d,r,u]=basis(),q=[p[0]-c[0],p[1]-c[1],p[2]-c[2]],
 s=0.48*Math.min(cv.width,cv.height)/R*zoom;
 return [cv.width/2+s*(q[0]*r[0]+q[1]*r[1]+q[2]*r[2]),cv.height/2-s*(q[0]*u[0]+q[1]*u[1]+q[2]*u[2]),
  q[0]*d[0]+q[1]*d[1]+q[2]*d[2]];}
function shade(hex,k){const n=parseInt(hex.slice(1),16);
 return "rgb("+[n>>16,(n>>8)&255,n&255].map(x=>Math.round(x*k)).join(",")+")";}
function draw(){const [d]=basis(),items=[];
 D.meshes.forEach(m=>{const P=[];for(let i=0;i<m.v.length;i+=3)P.push(project([m.v[i],m.v[i+1],m.v[i+2]]));
  for(let i=0;i<m.f.length;i+=3){const a=m.f[i]*3,b=m.f[i+1]*3,e=m.f[i+2]*3,
   A=[m.v[a],m.v[a+1],m.v[a+2]],B=[m.v[b],m.v[b+1],m.v[b+2]],C=[m.v[e],m.v[e+1],m.v[e+2]],
   x=[B[0]-A[0],B[1]-A[1],B[2]-A[2]],y=[C[0]-A[0],C[1]-A[1],C[2]-A[2]],
   n=[x[1]*y[2]-x[2]*y[1],x[2]*y[0]-x[0]*y[2],x[0]*y[1]-x[1]*y[0]],nn=Math.hypot(n[0],n[1],n[2])||1,
   lit=0.45+0.55*Math.abs((n[0]*d[0]+n[1]*d[1]+n[2]*d[2])/nn),p=[P[m.f[i]],P[m.f[i+1]],P[m.f[i+2]]];
   items.push({z:(p[0][2]+p[1][2]+p[2][2])/3,t:p,c:shade(m.c,lit)});}});
 const shown=D.lines.concat(D.points,D.steps.length?D.steps[step]:[]);
 shown.forEach(l=>{if(l.s!==undefined){const p=project(l.p);items.push({z:p[2],pt:p,c:l.c,s:l.s});return;}
  let prev=null;for(let i=0;i<l.p.length;i+=3){const p=project([l.p[i],l.p[i+1],l.p[i+2]]);
   if(prev)items.push({z:(prev[2]+p[2])/2,a:prev,b:p,c:l.c,w:l.w,d:l.d});prev=p;}});
 items.sort((a,b)=>a.z-b.z);g.clearRect(0,0,cv.width,cv.height);g.lineCap="round";
 for(const it of items){if(it.t){g.globalAlpha=0.7;g.fillStyle=it.c;g.beginPath();g.moveTo(it.t[0][0],it.t[0][1]);
   g.lineTo(it.t[1][0],it.t[1][1]);g.lineTo(it.t[2][0],it.t[2][1]);g.closePath();g.fill();g.globalAlpha=1;}
  else if(it.pt){g.fillStyle=it.c;g.fillRect(it.pt[0]-it.s,it.pt[1]-it.s,2*it.s,2*it.s);}
  else{g.strokeStyle=it.c;g.lineWidth=it.w;g.setLineDash(it.d?[6,4]:[]);g.beginPath();
   g.moveTo(it.a[0],it.a[1]);g.lineTo(it.b[0],it.b[1]);g.stroke();}}
 g.setLineDash([]);if(label&&D.labels.length)label.textContent=D.labels[step];root.dataset.drawn=items.length;}
let drag=null;
cv.addEventListener("pointerdown",e=>{drag=[e.clientX,e.clientY];cv.setPointerCapture(e.pointerId);});
cv.addEventListener("pointermove",e=>{if(!drag)return;yaw-=(e.clientX-drag[0])*0.01;
 pitch=Math.max(-1.55,Math.min(1.55,pitch+(e.clientY-drag[1])*0.01));drag=[e.clientX,e.clientY];draw();});
cv.addEventListener("pointerup",()=>{drag=null;});
cv.addEventListener("wheel",e=>{e.preventDefault();zoom*=Math.exp(-e.deltaY*0.001);draw();},{passive:false});
cv.addEventListener("dblclick",()=>{yaw=-0.9;pitch=0.45;zoom=1;draw();});
if(slider)slider.addEventListener("input",()=>{step=+slider.value;draw();});
(window.pliantViews=window.pliantViews||{})["__ID__"]={project:project,
 show:k=>{step=k;if(slider)slider.value=k;draw();},turn:(dy,dp)=>{yaw+=dy;pitch+=dp;draw();}};
draw();})();
